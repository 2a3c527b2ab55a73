-- schema/0006_job_counters.sql: how many times jobs of each kind entered each state, and how many
-- of their leases were rescued, kept by triggers in the transaction that changes the job.
CREATE TABLE job_counters (
  kind   text NOT NULL,
  event  text NOT NULL,  -- a job state, or 'rescue'
  n      bigint NOT NULL DEFAULT 0,
  PRIMARY KEY (kind, event)
);

INSERT INTO job_counters(kind, event, n) SELECT kind, state, COUNT(*) FROM jobs GROUP BY kind, state;
INSERT INTO job_counters(kind, event, n)
  SELECT kind, 'rescue', SUM(rescues) FROM jobs GROUP BY kind HAVING SUM(rescues) > 0;

CREATE FUNCTION job_counters_count(kind text, event text, n bigint) RETURNS void LANGUAGE sql AS
  $$ INSERT INTO job_counters(kind, event, n) VALUES (kind, event, n)
       ON CONFLICT (kind, event) DO UPDATE SET n = job_counters.n + excluded.n $$;

CREATE FUNCTION job_counters_insert() RETURNS trigger LANGUAGE plpgsql AS
  $$ BEGIN PERFORM job_counters_count(NEW.kind, NEW.state, 1); RETURN NULL; END $$;
CREATE TRIGGER job_counters_insert AFTER INSERT ON jobs
  FOR EACH ROW EXECUTE FUNCTION job_counters_insert();

CREATE FUNCTION job_counters_state() RETURNS trigger LANGUAGE plpgsql AS
  $$ BEGIN PERFORM job_counters_count(NEW.kind, NEW.state, 1); RETURN NULL; END $$;
CREATE TRIGGER job_counters_state AFTER UPDATE OF state ON jobs
  FOR EACH ROW WHEN (NEW.state <> OLD.state) EXECUTE FUNCTION job_counters_state();

CREATE FUNCTION job_counters_rescue() RETURNS trigger LANGUAGE plpgsql AS
  $$ BEGIN PERFORM job_counters_count(NEW.kind, 'rescue', NEW.rescues - OLD.rescues); RETURN NULL; END $$;
CREATE TRIGGER job_counters_rescue AFTER UPDATE OF rescues ON jobs
  FOR EACH ROW WHEN (NEW.rescues > OLD.rescues) EXECUTE FUNCTION job_counters_rescue();
