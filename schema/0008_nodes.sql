-- The daemons sharing this store (a fleet on PostgreSQL; one row on a single machine): each beats
-- its row while it runs and removes it when it stops. One of them holds the leader lease and runs
-- the maintenance every node need not repeat (webhook dispatch); a leader that stops beating is
-- replaced once its lease runs out.
CREATE TABLE nodes (
  name        TEXT PRIMARY KEY,
  workers     INTEGER NOT NULL DEFAULT 0,
  started_at  INTEGER NOT NULL,
  seen_at     INTEGER NOT NULL
);

CREATE TABLE leader (
  id     INTEGER PRIMARY KEY CHECK (id = 1),
  node   TEXT NOT NULL,
  until  INTEGER NOT NULL
);
