-- schema/0004_job_rescues.sql: how often a job was taken back from a worker that stopped
-- heartbeating; rescues do not spend attempts, and a job rescued too often is discarded.
ALTER TABLE jobs ADD COLUMN rescues integer NOT NULL DEFAULT 0 CHECK (rescues >= 0);
