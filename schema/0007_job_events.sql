-- The final states jobs reach (completed, discarded, cancelled), written by a trigger in the
-- transaction that changes the job, whoever changes it. meshmarkd turns each into one webhook
-- delivery job per configured endpoint (docs/api.md); webhook jobs raise no events themselves.
CREATE TABLE job_events (
  id      INTEGER PRIMARY KEY,
  job_id  INTEGER NOT NULL,
  kind    TEXT NOT NULL,
  state   TEXT NOT NULL,
  at      INTEGER NOT NULL
);

-- How far each consumer of job_events has read (consume_job_events in store.h).
CREATE TABLE event_cursors (
  consumer       TEXT PRIMARY KEY,
  last_event_id  INTEGER NOT NULL
) WITHOUT ROWID;

CREATE TRIGGER job_events_final AFTER UPDATE OF state ON jobs
  WHEN NEW.state <> OLD.state AND NEW.state IN ('completed', 'discarded', 'cancelled') AND NEW.kind <> 'webhook'
BEGIN
  INSERT INTO job_events(job_id, kind, state, at)
    VALUES (NEW.id, NEW.kind, NEW.state,
            COALESCE(NEW.finished_at, CAST((julianday('now') - 2440587.5) * 86400000 AS INTEGER)));
END;
