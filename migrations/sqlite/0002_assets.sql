-- Uploaded meshes (POST /assets), content-addressed: the id is the SHA-256 of the uploaded
-- bytes. `mesh` is the parsed mesh in drape's compact form (deflated arrays); `bytes` the size
-- of the upload, which the storage limit counts.
CREATE TABLE assets (
    seq        INTEGER PRIMARY KEY AUTOINCREMENT,
    id         TEXT NOT NULL UNIQUE,
    vertices   INTEGER NOT NULL,
    triangles  INTEGER NOT NULL,
    bytes      INTEGER NOT NULL,
    created_ms INTEGER NOT NULL,
    mesh       BLOB NOT NULL
);
