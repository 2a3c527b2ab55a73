-- How often a job was taken back from a worker that stopped heartbeating (killed, crashed, lost
-- its machine). Rescues do not spend the job's attempts (max_attempts counts the job's own
-- failures); a job rescued kMaxRescues times (store.h) is discarded, since it may be what kills
-- its workers.
ALTER TABLE jobs ADD COLUMN rescues INTEGER NOT NULL DEFAULT 0 CHECK (rescues >= 0);
