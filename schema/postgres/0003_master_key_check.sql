-- schema/0003_master_key_check.sql: a check value of the master key (BLAKE2b keyed with it over a
-- fixed label), so a wrong key is refused before anything is sealed under it. One row.
CREATE TABLE master_key_check (
  id          integer PRIMARY KEY CHECK (id = 1),
  check_value bytea NOT NULL CHECK (octet_length(check_value) = 32),
  created_at  bigint NOT NULL
);
