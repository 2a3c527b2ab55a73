// Evidence for legal teams: `evidence DETECTION OUT_DIR` writes a detection's signed package,
// `evidence pubkey` prints the installation's signing public key, `verify PACKAGE` checks a
// package (signature, every hash, the timestamp) and names what failed, `reproduce DETECTION`
// recomputes a detection and compares it with its record. docs/evidence.md.
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "service/evidence_package.h"
#include "store/home.h"

namespace mm::cli {
namespace {

struct EvidenceArgs {
  std::vector<std::string> args;
  std::string home, case_id, chromium, tsa_url, tsa_ca;
  bool no_pdf = false;
};

struct VerifyArgs {
  std::string package, home, tsa_ca;
  std::vector<std::string> pubkeys, files;
};

std::string read_text(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw CommandFailed(1, path + ": cannot read");
  std::string s;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) s.append(buf, n);
  std::fclose(f);
  return s;
}

void run_evidence(const EvidenceArgs& a) {
  const store::HomePaths home = store::resolve_home(a.home);
  if (a.args.size() == 1 && a.args[0] == "pubkey") {
    auto st = store::open_home(home, false);  // refuses a folder that is not a home
    const keys::SigningKey k =
        keys::load_or_create_signing_key(service::signing_key_path(home), service::signing_public_dir(home));
    std::printf("%s\n", k.public_key().text().c_str());
    return;
  }
  if (a.args.size() == 1 && a.args[0] == "rotate-key") {
    auto st = store::open_home(home, false);
    const keys::SigningKey k = keys::rotate_signing_key(service::signing_key_path(home), service::signing_public_dir(home));
    st->append_audit({"cli", "evidence.key.rotate", "signing-key:" + k.public_key().id(), "{}"});
    std::printf("new signing key %s; earlier keys stay trusted by verify --home (%s)\n%s\n",
                k.public_key().id().c_str(), service::signing_public_dir(home).c_str(), k.public_key().text().c_str());
    return;
  }
  if (a.args.size() != 2)
    throw CLI::ValidationError("evidence", "expected DETECTION OUT_DIR, pubkey or rotate-key");
  std::int64_t id = 0;
  try {
    std::size_t used = 0;
    id = std::stoll(a.args[0], &used);
    if (used != a.args[0].size() || id <= 0) throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw CLI::ValidationError("DETECTION", "'" + a.args[0] + "' is not a detection id (meshmark detections lists them)");
  }
  auto st = store::open_home(home, false);
  service::EvidenceOptions o;
  o.case_id = a.case_id;
  o.chromium = a.no_pdf ? "none" : a.chromium;
  o.tsa_url = a.tsa_url;
  o.tsa_ca_file = a.tsa_ca;
  service::EvidencePackage p;
  try {
    p = service::write_evidence_package(*st, home, id, a.args[1], o);
  } catch (const keys::KeyError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw CommandFailed(1, e.what());
  }
  std::printf("evidence package %s (signed by key %s)\n", p.dir.c_str(), p.key_id.c_str());
  for (const auto& f : p.files) std::printf("  %s\n", f.c_str());
  if (!p.pdf_note.empty()) std::printf("  %s\n", p.pdf_note.c_str());
  std::printf("  timestamp: %s\n", p.timestamp_note.c_str());
}

void run_verify(const VerifyArgs& a) {
  std::vector<keys::PublicKey> trusted;
  for (const auto& f : a.pubkeys) trusted.push_back(keys::PublicKey::parse(read_text(f), f));
  std::unique_ptr<store::Store> st;
  if (!a.home.empty() || std::getenv("MESHMARK_HOME")) {
    const store::HomePaths home = store::resolve_home(a.home);
    st = store::open_home(home, false);
    for (const auto& k : keys::recorded_public_keys(service::signing_public_dir(home))) trusted.push_back(k);
  }
  const service::VerifyReport r =
      service::verify_evidence_package(a.package, trusted, a.files, st ? &st->blobs() : nullptr, a.tsa_ca);
  for (const auto& s : r.passed) std::printf("ok      %s\n", s.c_str());
  for (const auto& s : r.skipped) std::printf("skipped %s\n", s.c_str());
  for (const auto& s : r.failed) std::printf("FAILED  %s\n", s.c_str());
  if (!r.ok())
    throw CommandFailed(1, a.package + ": does not verify (" + std::to_string(r.failed.size()) + " check(s) failed)");
  std::printf("%s: verifies\n", a.package.c_str());
}

void run_reproduce(const std::string& home_option, std::int64_t id) {
  auto st = store::open_home(store::resolve_home(home_option), true);  // the customer keys
  service::Reproduction r;
  try {
    r = service::reproduce_detection(*st, id);
  } catch (const std::runtime_error& e) {
    throw CommandFailed(1, e.what());
  }
  const auto rec = nlohmann::json::parse(r.recorded_json), now = nlohmann::json::parse(r.recomputed_json);
  std::printf("detection %lld recomputed from the stored records\n", static_cast<long long>(id));
  std::printf("  verdict          %s (recorded %s)\n", now["verdict"].get<std::string>().c_str(),
              rec["verdict"].get<std::string>().c_str());
  std::printf("  corrected p      %s (recorded %s)\n", now["p_value"].dump().c_str(), rec["p_value"].dump().c_str());
  for (const auto& c : now["details"].value("candidates", nlohmann::json::array()))
    for (const auto& s : c.value("copies", nlohmann::json::array()))
      std::printf("  copy %-6lld     corrected p %s, sign -log10 p %s, matched -log10 p %s\n",
                  static_cast<long long>(s.value("copy_id", 0LL)), s["p_value"].dump().c_str(),
                  s["sign_neg_log10_p"].dump().c_str(), s["matched_neg_log10_p"].dump().c_str());
  if (r.identical()) {
    std::printf("identical: all %d numbers and every field as recorded, bit for bit\n", r.numbers_compared);
    return;
  }
  for (const auto& d : r.differences) std::printf("DIFFERS  %s\n", d.c_str());
  throw CommandFailed(1, "detection " + std::to_string(id) + ": " + std::to_string(r.differences.size()) +
                             " field(s) differ from the record");
}

}  // namespace

void add_evidence_commands(CLI::App& app) {
  auto e = std::make_shared<EvidenceArgs>();
  auto* ev = app.add_subcommand("evidence", "Write a detection's signed evidence package; evidence pubkey prints "
                                            "the signing public key, evidence rotate-key replaces the key");
  ev->add_option("args", e->args, "DETECTION OUT_DIR, pubkey or rotate-key")->required()->expected(1, 2);
  ev->add_option("--home", e->home, "meshmark home folder (default: $MESHMARK_HOME or ./meshmark-home)");
  ev->add_option("--case-id", e->case_id, "case id printed on the report (default MM-<detection>-<suspect hash>)");
  ev->add_flag("--no-pdf", e->no_pdf, "do not print the report to PDF");
  ev->add_option("--chromium", e->chromium, "browser used for the PDF (default: chromium on PATH)");
  ev->add_option("--tsa-url", e->tsa_url, "RFC 3161 time-stamping authority to timestamp the statement");
  ev->add_option("--tsa-ca", e->tsa_ca, "the authority's CA certificate (PEM), to check its reply");
  ev->callback([e] { refusing_store_errors([e] { run_evidence(*e); }); });

  auto v = std::make_shared<VerifyArgs>();
  auto* ve = app.add_subcommand("verify", "Check an evidence package: signature, every hash, the timestamp");
  ve->add_option("package", v->package, "the package folder")->required();
  ve->add_option("--pubkey", v->pubkeys, "trusted signing public key file (from meshmark evidence pubkey)");
  ve->add_option("--home", v->home, "trust this home's signing keys and look up files in its blob store");
  ve->add_option("--file", v->files, "a referenced file at hand (suspect, original, issued copy) to check");
  ve->add_option("--tsa-ca", v->tsa_ca, "CA certificate (PEM) of the time-stamping authority");
  ve->callback([v] { refusing_store_errors([v] { run_verify(*v); }); });

  auto rh = std::make_shared<std::string>();
  auto rid = std::make_shared<std::int64_t>(0);
  auto* re = app.add_subcommand("reproduce", "Recompute a stored detection and compare it with its record");
  re->add_option("detection", *rid, "detection id (meshmark detections lists them)")->required()->check(CLI::PositiveNumber);
  re->add_option("--home", *rh, "meshmark home folder (default: $MESHMARK_HOME or ./meshmark-home)");
  re->callback([rh, rid] { refusing_store_errors([rh, rid] { run_reproduce(*rh, *rid); }); });
}

}  // namespace mm::cli
