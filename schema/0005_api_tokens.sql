-- API tokens (meshmark token create|list|revoke): clients of meshmarkd's HTTP API authenticate with
-- a bearer token. Only its SHA-256 is stored; the token itself is shown once, when created.
-- role: read (status, lists, downloads), submit (read, upload, submit, cancel), admin (all, retry).
CREATE TABLE api_tokens (
  id            INTEGER PRIMARY KEY,
  name          TEXT NOT NULL UNIQUE,
  role          TEXT NOT NULL CHECK (role IN ('read', 'submit', 'admin')),
  token_sha256  TEXT NOT NULL UNIQUE CHECK (length(token_sha256) = 64),
  created_at    INTEGER NOT NULL,
  revoked_at    INTEGER
);
