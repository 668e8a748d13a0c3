-- Sweeps (POST /sweeps): one row per sweep with its document, and one row per run (the
-- reference is run 0 when there is one, then the variants in order). A run is claimed under a
-- lease like a job and keeps only what the sweep's table needs: its status, why it failed, and
-- its result (final positions and statistics as JSON, deflate-compressed).
CREATE TABLE sweeps (
    seq              BIGSERIAL PRIMARY KEY,
    id               TEXT NOT NULL UNIQUE,
    created_ms       BIGINT NOT NULL,
    runs             BIGINT NOT NULL,
    has_reference    BOOLEAN NOT NULL,
    document         TEXT NOT NULL,
    cancel_requested BOOLEAN NOT NULL DEFAULT FALSE
);

CREATE TABLE sweep_runs (
    seq              BIGSERIAL PRIMARY KEY,
    sweep_id         TEXT NOT NULL REFERENCES sweeps (id) ON DELETE CASCADE,
    idx              BIGINT NOT NULL,
    status           TEXT NOT NULL,
    attempts         BIGINT NOT NULL DEFAULT 0,
    lease_owner      TEXT,
    lease_until_ms   BIGINT,
    cancel_requested BOOLEAN NOT NULL DEFAULT FALSE,
    message          TEXT,
    result           BYTEA,
    UNIQUE (sweep_id, idx)
);

-- Claiming looks only at runs that have not ended, oldest first.
CREATE INDEX sweep_runs_open ON sweep_runs (seq) WHERE status IN ('queued', 'running');
CREATE INDEX sweep_runs_owner ON sweep_runs (lease_owner) WHERE status = 'running';
