-- Counters behind meshmarkd's /metrics (docs/api.md): how many times jobs of each kind entered each
-- state, and how many of their leases were rescued. Kept by triggers, so every writer (the store,
-- a PDM system inserting rows, docs/queue-contract.md) is counted in the transaction that changes
-- the job, and the counts only grow (a retry enters 'available' again). Seeded from the jobs present.
CREATE TABLE job_counters (
  kind   TEXT NOT NULL,
  event  TEXT NOT NULL,  -- a job state, or 'rescue'
  n      INTEGER NOT NULL DEFAULT 0,
  PRIMARY KEY (kind, event)
) WITHOUT ROWID;

INSERT INTO job_counters(kind, event, n) SELECT kind, state, COUNT(*) FROM jobs GROUP BY kind, state;
INSERT INTO job_counters(kind, event, n)
  SELECT kind, 'rescue', SUM(rescues) FROM jobs GROUP BY kind HAVING SUM(rescues) > 0;

CREATE TRIGGER job_counters_insert AFTER INSERT ON jobs BEGIN
  INSERT INTO job_counters(kind, event, n) VALUES (NEW.kind, NEW.state, 1)
    ON CONFLICT(kind, event) DO UPDATE SET n = n + 1;
END;

CREATE TRIGGER job_counters_state AFTER UPDATE OF state ON jobs WHEN NEW.state <> OLD.state BEGIN
  INSERT INTO job_counters(kind, event, n) VALUES (NEW.kind, NEW.state, 1)
    ON CONFLICT(kind, event) DO UPDATE SET n = n + 1;
END;

CREATE TRIGGER job_counters_rescue AFTER UPDATE OF rescues ON jobs WHEN NEW.rescues > OLD.rescues BEGIN
  INSERT INTO job_counters(kind, event, n) VALUES (NEW.kind, 'rescue', NEW.rescues - OLD.rescues)
    ON CONFLICT(kind, event) DO UPDATE SET n = n + excluded.n;
END;
