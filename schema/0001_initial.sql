-- meshmark store, first schema. Times are integer milliseconds since the Unix epoch (UTC).
-- Applied by the store at start-up inside one transaction; recorded in schema_version.

CREATE TABLE customers (
  id            INTEGER PRIMARY KEY,
  name          TEXT NOT NULL UNIQUE,
  current_key_version INTEGER NOT NULL DEFAULT 0,
  created_at    INTEGER NOT NULL
);

-- Customer keys sealed with XChaCha20-Poly1305 under the master key (which is never stored here).
CREATE TABLE customer_keys (
  customer_id   INTEGER NOT NULL REFERENCES customers(id),
  version       INTEGER NOT NULL CHECK (version >= 1),
  nonce         BLOB NOT NULL CHECK (length(nonce) = 24),
  ciphertext    BLOB NOT NULL CHECK (length(ciphertext) = 48),
  created_at    INTEGER NOT NULL,
  PRIMARY KEY (customer_id, version)
);

CREATE TABLE assets (
  id            INTEGER PRIMARY KEY,
  sha256        TEXT NOT NULL UNIQUE CHECK (length(sha256) = 64),
  size          INTEGER NOT NULL,
  name          TEXT NOT NULL,
  format        TEXT NOT NULL,
  created_at    INTEGER NOT NULL
);

CREATE TABLE polyhedra (
  id              INTEGER PRIMARY KEY,
  asset_id        INTEGER NOT NULL REFERENCES assets(id),
  params_key      TEXT NOT NULL,
  polyhedron_blob TEXT NOT NULL,
  basis_blob      TEXT NOT NULL DEFAULT '',
  meta_json       TEXT NOT NULL DEFAULT '{}',
  created_at      INTEGER NOT NULL,
  UNIQUE (asset_id, params_key)
);

-- The job queue. docs/queue-contract.md documents how other systems may insert rows directly.
CREATE TABLE jobs (
  id              INTEGER PRIMARY KEY,
  kind            TEXT NOT NULL CHECK (length(kind) > 0),
  payload_json    TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(payload_json)),
  state           TEXT NOT NULL DEFAULT 'available'
                  CHECK (state IN ('available','running','completed','retryable','discarded','cancelled')),
  priority        INTEGER NOT NULL DEFAULT 0,
  attempt         INTEGER NOT NULL DEFAULT 0 CHECK (attempt >= 0),
  max_attempts    INTEGER NOT NULL DEFAULT 5 CHECK (max_attempts >= 1),
  idempotency_key TEXT UNIQUE,
  created_at      INTEGER NOT NULL DEFAULT (CAST((julianday('now') - 2440587.5) * 86400000 AS INTEGER)),
  scheduled_at    INTEGER NOT NULL DEFAULT (CAST((julianday('now') - 2440587.5) * 86400000 AS INTEGER)),
  attempted_at    INTEGER,
  finished_at     INTEGER,
  worker_id       TEXT NOT NULL DEFAULT '',
  lease_until     INTEGER,
  errors_json     TEXT NOT NULL DEFAULT '[]' CHECK (json_valid(errors_json)),
  result_json     TEXT NOT NULL DEFAULT '',
  CHECK (state <> 'running' OR lease_until IS NOT NULL)
);
-- The claim query walks this index: best priority, then earliest schedule, then oldest id.
CREATE INDEX jobs_claim ON jobs (state, priority DESC, scheduled_at, id);
CREATE INDEX jobs_lease ON jobs (lease_until) WHERE state = 'running';

CREATE TABLE issued_copies (
  id              INTEGER PRIMARY KEY,
  asset_id        INTEGER NOT NULL REFERENCES assets(id),
  customer_id     INTEGER NOT NULL REFERENCES customers(id),
  key_version     INTEGER NOT NULL,
  idempotency_key TEXT NOT NULL DEFAULT '',
  nonce           BLOB NOT NULL,
  payload_hex     TEXT NOT NULL,
  params_json     TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(params_json)),
  outputs_json    TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(outputs_json)),
  polyhedron_id   INTEGER REFERENCES polyhedra(id),
  job_id          INTEGER REFERENCES jobs(id),
  created_at      INTEGER NOT NULL,
  UNIQUE (asset_id, customer_id, key_version, idempotency_key),
  FOREIGN KEY (customer_id, key_version) REFERENCES customer_keys(customer_id, version)
);
CREATE INDEX issued_copies_asset ON issued_copies (asset_id);

CREATE TABLE detections (
  id                  INTEGER PRIMARY KEY,
  job_id              INTEGER REFERENCES jobs(id),
  suspect_sha256      TEXT NOT NULL,
  suspect_name        TEXT NOT NULL DEFAULT '',
  verdict             TEXT NOT NULL,
  asset_id            INTEGER REFERENCES assets(id),
  copy_id             INTEGER REFERENCES issued_copies(id),
  customer_id         INTEGER REFERENCES customers(id),
  correlation         REAL,
  p_value             REAL,
  decoded_payload_hex TEXT NOT NULL DEFAULT '',
  details_json        TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(details_json)),
  created_at          INTEGER NOT NULL
);

-- Append-only: rows are inserted, never changed or removed.
CREATE TABLE audit_log (
  id            INTEGER PRIMARY KEY,
  at            INTEGER NOT NULL,
  actor         TEXT NOT NULL,
  action        TEXT NOT NULL,
  subject       TEXT NOT NULL DEFAULT '',
  details_json  TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(details_json))
);
CREATE TRIGGER audit_log_no_update BEFORE UPDATE ON audit_log
BEGIN
  SELECT RAISE(ABORT, 'audit_log is append-only');
END;
CREATE TRIGGER audit_log_no_delete BEFORE DELETE ON audit_log
BEGIN
  SELECT RAISE(ABORT, 'audit_log is append-only');
END;
