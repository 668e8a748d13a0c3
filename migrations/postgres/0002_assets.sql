-- Uploaded meshes (POST /assets), content-addressed: the id is the SHA-256 of the uploaded
-- bytes. `mesh` is the parsed mesh in drape's compact form (deflated arrays); `bytes` the size
-- of the upload, which the storage limit counts.
CREATE TABLE assets (
    seq        BIGSERIAL PRIMARY KEY,
    id         TEXT NOT NULL UNIQUE,
    vertices   BIGINT NOT NULL,
    triangles  BIGINT NOT NULL,
    bytes      BIGINT NOT NULL,
    created_ms BIGINT NOT NULL,
    mesh       BYTEA NOT NULL
);
