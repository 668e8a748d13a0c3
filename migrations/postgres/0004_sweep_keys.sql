-- A sweep's Idempotency-Key and the fingerprint of the document first sent with it, so a
-- repeated POST /sweeps finds the sweep it made, on any instance sharing the store.
ALTER TABLE sweeps ADD COLUMN idem_key TEXT;
ALTER TABLE sweeps ADD COLUMN idem_fingerprint BIGINT;
CREATE UNIQUE INDEX sweeps_idem_key ON sweeps (idem_key);
