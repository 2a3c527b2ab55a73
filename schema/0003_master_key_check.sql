-- A check value of the master key: BLAKE2b keyed with the master key over a fixed label, so a
-- wrong key is refused when the store is opened, before anything is sealed under it. Reveals
-- nothing about the key. One row, written when a key is first used with the store.
CREATE TABLE master_key_check (
  id          INTEGER PRIMARY KEY CHECK (id = 1),
  check_value BLOB NOT NULL CHECK (length(check_value) = 32),
  created_at  INTEGER NOT NULL
);
