-- schema/0010_job_pruning.sql: finished jobs no record points at are pruned after the retention
-- (Store::prune_jobs), found by when they finished; the records' references to their job by index.
CREATE INDEX jobs_finished ON jobs (finished_at) WHERE state IN ('completed', 'discarded', 'cancelled');
CREATE INDEX issued_copies_job ON issued_copies (job_id);
CREATE INDEX detections_job ON detections (job_id);
