// A detection's evidence package: what a legal team takes to a lawyer, and how anyone checks it.
//
// write_evidence_package() writes, into a new folder:
//   statement.json       an in-toto v1 Statement: subjects are the files by SHA-256 (the report,
//                        the PDF, and the suspect, the original, the issued stream and decoded
//                        copy it refers to); the predicate holds the verdict, every copy's
//                        statistics, the method's measured false-attribution rate, the chain of
//                        records, versions and parameters (never a key)
//   statement.dsse.json  the statement signed (DSSE envelope, Ed25519, the installation's key)
//   report.html          self-contained page, pictures embedded (jobs/evidence_report.h)
//   report.pdf           the page printed by headless Chromium, when it is installed
//   statement.tsr        an RFC 3161 timestamp of statement.json, when an authority is configured,
//   statement.tsr.dsse.json  with its SHA-256 signed (the reply's certificates are not covered by
//                        the authority's own signature)
// The folder appears whole or not at all (written beside it, then renamed).
//
// verify_evidence_package() checks all of that and names what failed.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "keys/signing.h"
#include "store/home.h"
#include "store/store.h"

namespace mm::service {

constexpr const char* kStatementType = "https://in-toto.io/Statement/v1";
constexpr const char* kPredicateType = "https://meshmark.dev/detection-evidence/v1";
constexpr const char* kTimestampPredicateType = "https://meshmark.dev/detection-evidence-timestamp/v1";
constexpr const char* kDssePayloadType = "application/vnd.in-toto+json";

struct EvidenceOptions {
  std::string case_id;   // "" = MM-<detection id>-<first 12 hex of the suspect's SHA-256>
  std::string chromium;  // browser for the PDF: "" = `chromium` on PATH, "none" = no PDF
  std::string tsa_url;   // RFC 3161 authority ("" = no timestamp requested)
  std::string tsa_ca_file;  // its CA certificate, checked right after the reply arrives
};

struct EvidencePackage {
  std::string dir;
  std::vector<std::string> files;  // written, relative to dir
  std::string key_id;              // signing key
  std::string pdf_note;            // why there is no PDF, "" when there is one
  std::string timestamp_note;      // "none requested" or the authority's
};

// Throws std::runtime_error naming the detection, file or step that failed; leaves nothing at
// out_dir then. out_dir must not exist or be an empty folder.
EvidencePackage write_evidence_package(store::Store& st, const store::HomePaths& home, std::int64_t detection_id,
                                       const std::string& out_dir, const EvidenceOptions& options = {});

// The DSSE pre-authentication encoding that is signed: "DSSEv1 <len> <type> <len> <body>".
std::string dsse_pae(const std::string& payload_type, const std::string& payload);

struct VerifyReport {
  std::vector<std::string> passed;   // "signature: key 3f2a... (trusted)"
  std::vector<std::string> failed;   // "report.html: SHA-256 differs from the statement's"
  std::vector<std::string> skipped;  // "suspect fandisk.off: not at hand"
  bool ok() const { return failed.empty(); }
};

// trusted: the public keys accepted as signers (a package signed by another key fails).
// referenced: files the caller has at hand (any name; matched to subjects by digest); blobs, when
// given, is searched by digest too, and a subject's recorded location is tried last.
VerifyReport verify_evidence_package(const std::string& dir, const std::vector<keys::PublicKey>& trusted,
                                     const std::vector<std::string>& referenced = {},
                                     const store::BlobStore* blobs = nullptr, const std::string& tsa_ca_file = "");

// A stored detection computed again from the stored records alone (the suspect from the blob
// store, the copies, keys and polyhedra from the store, the parameters it recorded), compared
// field by field with what was recorded (every number of every copy; its wall time aside).
struct Reproduction {
  std::string recorded_json, recomputed_json;  // the compared records
  std::vector<std::string> differences;        // "/candidates/0/copies/1/matched_statistic: 12.5 recorded, 12.4 now"
  int numbers_compared = 0;
  bool identical() const { return differences.empty(); }
};
// Throws std::runtime_error naming the detection and what is missing (no such detection, the
// suspect's bytes not in the blob store).
Reproduction reproduce_detection(store::Store& st, std::int64_t detection_id);

// <home>/signing.key and <home>/signing-keys/.
std::string signing_key_path(const store::HomePaths& home);
std::string signing_public_dir(const store::HomePaths& home);

}  // namespace mm::service
