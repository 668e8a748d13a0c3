-- Jobs, their queue state and their results.
CREATE TABLE jobs (
    seq              BIGSERIAL PRIMARY KEY,
    id               TEXT NOT NULL UNIQUE,
    status           TEXT NOT NULL,
    created_ms       BIGINT NOT NULL,
    started_ms       BIGINT,
    finished_ms      BIGINT,
    particles        BIGINT NOT NULL,
    springs          BIGINT NOT NULL,
    steps            BIGINT NOT NULL,
    companion_steps  BIGINT NOT NULL DEFAULT 0,
    dt               DOUBLE PRECISION NOT NULL,
    duration         DOUBLE PRECISION NOT NULL,
    steps_done       BIGINT NOT NULL DEFAULT 0,
    message          TEXT,
    failure          TEXT,
    stats            TEXT,
    idem_key         TEXT UNIQUE,
    idem_fingerprint BIGINT,
    -- The scene document; dropped when the job ends.
    scene            TEXT,
    attempts         BIGINT NOT NULL DEFAULT 0,
    lease_owner      TEXT,
    lease_until_ms   BIGINT,
    cancel_requested BOOLEAN NOT NULL DEFAULT FALSE,
    -- The sweep a job belongs to, once sweeps exist.
    sweep_id         TEXT
);

-- Claiming looks only at jobs that have not ended, oldest first.
CREATE INDEX jobs_open ON jobs (seq) WHERE status IN ('queued', 'running');
CREATE INDEX jobs_status ON jobs (status);
CREATE INDEX jobs_sweep ON jobs (sweep_id) WHERE sweep_id IS NOT NULL;

-- Results, stored once, deflate-compressed, dropped after the retention time.
CREATE TABLE results (
    job_id      TEXT PRIMARY KEY REFERENCES jobs (id) ON DELETE CASCADE,
    media_type  TEXT NOT NULL,
    body        BYTEA NOT NULL,
    finished_ms BIGINT NOT NULL
);
CREATE INDEX results_finished ON results (finished_ms);
