-- Jobs, their queue state and their results.
CREATE TABLE jobs (
    seq              INTEGER PRIMARY KEY AUTOINCREMENT,
    id               TEXT NOT NULL UNIQUE,
    status           TEXT NOT NULL,
    created_ms       INTEGER NOT NULL,
    started_ms       INTEGER,
    finished_ms      INTEGER,
    particles        INTEGER NOT NULL,
    springs          INTEGER NOT NULL,
    steps            INTEGER NOT NULL,
    companion_steps  INTEGER NOT NULL DEFAULT 0,
    dt               REAL NOT NULL,
    duration         REAL NOT NULL,
    steps_done       INTEGER NOT NULL DEFAULT 0,
    message          TEXT,
    failure          TEXT,
    stats            TEXT,
    idem_key         TEXT UNIQUE,
    idem_fingerprint INTEGER,
    -- The scene document; dropped when the job ends.
    scene            TEXT,
    attempts         INTEGER NOT NULL DEFAULT 0,
    lease_owner      TEXT,
    lease_until_ms   INTEGER,
    cancel_requested INTEGER NOT NULL DEFAULT 0,
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
    body        BLOB NOT NULL,
    finished_ms INTEGER NOT NULL
);
CREATE INDEX results_finished ON results (finished_ms);
