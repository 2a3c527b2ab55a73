-- Finished jobs no record points at are pruned after the retention (Store::prune_jobs): the
-- finished ones found by when they finished, and the records' references to their job looked up
-- by index rather than by a scan per job.
CREATE INDEX jobs_finished ON jobs (finished_at) WHERE state IN ('completed', 'discarded', 'cancelled');
CREATE INDEX issued_copies_job ON issued_copies (job_id);
CREATE INDEX detections_job ON detections (job_id);
