-- schema/0009_blobs.sql: on PostgreSQL this migration puts the blobs into the database (every node
-- of a fleet reads them there). A SQLite store keeps its blobs as files in the home's blobs/
-- folder (store/blob_store.h), so here it changes nothing; it exists to keep both backends'
-- versions in step.
SELECT 1;
