-- schema/0008_nodes.sql: the daemons sharing this store, each beating its row while it runs; the
-- one holding the leader lease (renewed on the database's clock) runs the maintenance every node
-- need not repeat, and a leader that stops beating is replaced once its lease runs out.
CREATE TABLE nodes (
  name        text PRIMARY KEY,
  workers     integer NOT NULL DEFAULT 0,
  started_at  bigint NOT NULL,
  seen_at     bigint NOT NULL
);

CREATE TABLE leader (
  id     integer PRIMARY KEY CHECK (id = 1),
  node   text NOT NULL,
  until  bigint NOT NULL
);
