-- schema/postgres/0009_blobs.sql: blobs (originals, control polyhedra, bases) in the database, so
-- every node of a fleet reads them without a shared folder. A blob is its row here and its bytes in
-- 1 MiB chunks, written in one transaction (store/pg_blob_store.h). The chunks are stored EXTERNAL:
-- out of line and not compressed again (meshes and streams are compact already).
CREATE TABLE blobs (
  sha256      text PRIMARY KEY,
  size        bigint NOT NULL,
  created_at  bigint NOT NULL
);

CREATE TABLE blob_chunks (
  sha256  text NOT NULL REFERENCES blobs(sha256) ON DELETE CASCADE,
  seq     integer NOT NULL,
  data    bytea NOT NULL,
  PRIMARY KEY (sha256, seq)
);
ALTER TABLE blob_chunks ALTER COLUMN data SET STORAGE EXTERNAL;

