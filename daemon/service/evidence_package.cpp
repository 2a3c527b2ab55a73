#include "service/evidence_package.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "cad/tessellate.h"
#include "jobs/detect_suspect.h"
#include "jobs/evidence_report.h"
#include "service/build_info.h"
#include "service/handlers.h"
#include "service/run_program.h"
#include "support/atomic_file.h"
#include "support/sha256.h"


namespace mm::service {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string iso_time(store::Millis ms) { return store::iso_utc(ms); }

json parsed(const std::string& text) {
  json j = json::parse(text, nullptr, false);
  return j.is_discarded() ? json(text) : j;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot read");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string sha256_of(const std::string& bytes) { return support::sha256_hex(bytes.data(), bytes.size()); }

// The statistic, in words a report can carry whatever the detector's internals.
const char* kStatistic =
    "Each issued copy was given its own pseudo-random displacement pattern, derived from its customer's secret key "
    "and a per-copy nonce, added to the spectral coefficients of the part's control polyhedron. The suspect is "
    "brought back into the original's vertex order and frame (resynchronisation), and each copy's pattern is "
    "tested against what the suspect shows: a sign count (how many coefficients moved the way the copy's pattern "
    "says, against the binomial tail and against an empirical null of unrelated sequences, whichever is larger) and "
    "a matched score (each coefficient weighted by the copy's known displacement, with Hoeffding's distribution-free "
    "bound). The copy's p-value is twice the smaller of the two.";
const char* kDecisionRule =
    "A customer is named only when their copy's p-value, multiplied by the number of copies tried (Bonferroni), "
    "is below the configured threshold; every copy below it is named (averaged copies carry several marks). The "
    "payload decoded from the suspect is reported beside it but does not decide.";

struct Subject {
  std::string name, sha256;
};

// A DSSE envelope of body, signed by signer.
std::string dsse_envelope(const keys::SigningKey& signer, const std::string& body) {
  const std::vector<std::uint8_t> sig = signer.sign(dsse_pae(kDssePayloadType, body));
  const json envelope{{"payloadType", kDssePayloadType},
                      {"payload", keys::to_base64(body)},
                      {"signatures", json::array({json{{"keyid", signer.public_key().id()},
                                                       {"sig", keys::to_base64(std::string(sig.begin(), sig.end()))}}})}};
  return envelope.dump(2) + "\n";
}

// An envelope's payload and the trusted key that signed it; `error` says what failed instead.
struct OpenedEnvelope {
  std::string body, signer, error;
};
OpenedEnvelope open_envelope(const fs::path& file, const std::vector<keys::PublicKey>& trusted) {
  OpenedEnvelope o;
  const std::string name = file.filename().string();
  json envelope;
  try {
    envelope = json::parse(read_file(file.string()));
    if (!envelope.is_object() || !envelope.contains("payloadType") || envelope["payloadType"] != kDssePayloadType) {
      o.error = name + ": payload type is not " + std::string(kDssePayloadType);
      return o;
    }
    o.body = keys::from_base64(envelope.at("payload").get<std::string>(), name + " payload");
  } catch (const std::exception& e) {
    o.error = name + ": unreadable envelope: " + e.what();
    return o;
  }
  const json signatures = envelope.contains("signatures") && envelope["signatures"].is_array()
                              ? envelope["signatures"] : json::array();
  for (const auto& sj : signatures) {
    // A signature entry of the wrong shape counts as no signature, never as an exception.
    if (!sj.is_object() || !sj.contains("sig") || !sj["sig"].is_string() || !sj.contains("keyid") ||
        !sj["keyid"].is_string())
      continue;
    std::string sig;
    try {
      sig = keys::from_base64(sj["sig"].get<std::string>(), "signature");
    } catch (const std::exception&) {
      continue;
    }
    for (const auto& k : trusted)
      if (sj["keyid"].get<std::string>() == k.id() &&
          keys::signature_valid(k, dsse_pae(kDssePayloadType, o.body), std::vector<std::uint8_t>(sig.begin(), sig.end())))
        o.signer = k.id();
  }
  if (trusted.empty())
    o.error = name + ": no trusted public key given (meshmark evidence pubkey exports the installation's)";
  else if (o.signer.empty())
    o.error = name + ": signature not valid for any trusted key (the file was altered, or another key signed it)";
  return o;
}

}  // namespace

namespace {

// The record as compared: the row's fields and its details, without the wall time.
json comparable(const store::NewDetection& d) {
  json details = parsed(d.details_json);
  details.erase("seconds");
  return {{"verdict", d.verdict},
          {"asset_id", d.asset_id ? json(*d.asset_id) : json(nullptr)},
          {"copy_id", d.copy_id ? json(*d.copy_id) : json(nullptr)},
          {"customer_id", d.customer_id ? json(*d.customer_id) : json(nullptr)},
          {"correlation", d.correlation ? json(*d.correlation) : json(nullptr)},
          {"p_value", d.p_value ? json(*d.p_value) : json(nullptr)},
          {"decoded_payload_hex", d.decoded_payload_hex},
          {"resync_method", d.resync_method},
          {"details", details}};
}

int count_numbers(const json& j) {
  if (j.is_number()) return 1;
  int n = 0;
  if (j.is_structured())
    for (const auto& e : j) n += count_numbers(e);
  return n;
}

}  // namespace

Reproduction reproduce_detection(store::Store& st, std::int64_t detection_id) {
  const std::string what = "detection " + std::to_string(detection_id);
  const auto det = st.get_detection(detection_id);
  if (!det) throw std::runtime_error("no " + what + " in the store");
  if (!st.blobs().contains(det->suspect_sha256))
    throw std::runtime_error(what + ": the suspect's bytes (SHA-256 " + det->suspect_sha256 +
                             ") are not in the blob store, so it cannot be recomputed");
  const json details = parsed(det->details_json);
  DetectParameters params;
  const json recorded_params = details.value("parameters", json::object());
  params.p_threshold = recorded_params.value("p_threshold", details.value("p_threshold", params.p_threshold));
  params.max_candidates = recorded_params.value("max_candidates", params.max_candidates);
  jobs::Suspect suspect;
  suspect.name = det->suspect_name;
  suspect.sha256 = det->suspect_sha256;
  suspect.mesh = read_named_mesh(st.blobs().get(det->suspect_sha256), det->suspect_name, &suspect.stream_metadata);
  const DetectionRecord now = detect_record(st, suspect, params);

  json before = comparable(*det), after = comparable(now.detection);
  // Who ran it is recorded, not recomputed: a newer build reproducing an old detection is the point.
  for (json* j : {&before, &after})
    if ((*j)["details"].contains("parameters")) {
      (*j)["details"]["parameters"].erase("meshmark_version");
      (*j)["details"]["parameters"].erase("build_sha256");
    }
  // Records older than these fields ran with the p threshold they state and the default
  // candidate count, which is what was used now.
  for (const char* k : {"parameters", "reason"})
    if (!before["details"].contains(k)) after["details"].erase(k);
  // Nor did they state each copy's strength, which came from the copy's own record then as now.
  if (before["details"].contains("candidates") && after["details"].contains("candidates"))
    for (std::size_t i = 0; i < before["details"]["candidates"].size() && i < after["details"]["candidates"].size(); ++i) {
      const json& was = before["details"]["candidates"][i].value("copies", json::array());
      json& is = after["details"]["candidates"][i]["copies"];
      for (std::size_t k = 0; k < was.size() && k < is.size(); ++k)
        if (!was[k].contains("strength")) is[k].erase("strength");
    }
  Reproduction r;
  r.recorded_json = before.dump();
  r.recomputed_json = after.dump();
  r.numbers_compared = count_numbers(before);
  for (const auto& op : json::diff(before, after)) {
    const std::string path = op.value("path", "");
    const json::json_pointer ptr(path);
    const std::string was = before.contains(ptr) ? before[ptr].dump() : "absent";
    const std::string is = after.contains(ptr) ? after[ptr].dump() : "absent";
    r.differences.push_back(path + ": " + was + " recorded, " + is + " now");
  }
  return r;
}

std::string signing_key_path(const store::HomePaths& home) { return home.root + "/signing.key"; }
std::string signing_public_dir(const store::HomePaths& home) { return home.root + "/signing-keys"; }

std::string dsse_pae(const std::string& payload_type, const std::string& payload) {
  return "DSSEv1 " + std::to_string(payload_type.size()) + " " + payload_type + " " + std::to_string(payload.size()) +
         " " + payload;
}

EvidencePackage write_evidence_package(store::Store& st, const store::HomePaths& home, std::int64_t detection_id,
                                       const std::string& out_dir, const EvidenceOptions& options) {
  const std::string what = "detection " + std::to_string(detection_id);
  const auto det = st.get_detection(detection_id);
  if (!det) throw std::runtime_error("no " + what + " in the store at " + home.root);
  if (fs::exists(out_dir) && !(fs::is_directory(out_dir) && fs::is_empty(out_dir)))
    throw std::runtime_error(out_dir + ": exists and is not an empty folder; refusing to overwrite it");
  const keys::SigningKey signer = keys::load_or_create_signing_key(signing_key_path(home), signing_public_dir(home));

  const json details = parsed(det->details_json);
  std::map<std::int64_t, std::string> customers;
  for (const auto& c : st.list_customers()) customers[c.id] = c.name;

  json records = json::object();
  json detection_row{{"id", det->id},
                     {"job_id", det->job_id ? json(*det->job_id) : json(nullptr)},
                     {"created_at", iso_time(det->created_at)},
                     {"suspect_name", det->suspect_name},
                     {"suspect_sha256", det->suspect_sha256},
                     {"verdict", det->verdict},
                     {"asset_id", det->asset_id ? json(*det->asset_id) : json(nullptr)},
                     {"copy_id", det->copy_id ? json(*det->copy_id) : json(nullptr)},
                     {"customer_id", det->customer_id ? json(*det->customer_id) : json(nullptr)},
                     {"p_value", det->p_value ? json(*det->p_value) : json(nullptr)},
                     {"decoded_payload_hex", det->decoded_payload_hex},
                     {"resync_method", det->resync_method},
                     {"details", details}};
  records["detection"] = detection_row;

  std::optional<store::Asset> asset;
  if (det->asset_id) asset = st.get_asset(*det->asset_id);
  if (asset)
    records["asset"] = {{"id", asset->id}, {"sha256", asset->sha256}, {"size", asset->size}, {"name", asset->name},
                        {"format", asset->format}, {"created_at", iso_time(asset->created_at)}};

  // Every copy tried, with its customer and scores, in the order tried.
  json copies = json::array();
  json copy_rows = json::array();
  std::map<std::int64_t, store::IssuedCopy> copy_of;
  std::vector<std::pair<std::string, double>> bars;
  double best_z = 0;
  std::vector<double> other_z;
  std::string best_label;
  const std::int64_t best_copy = details.value("best_copy_id", std::int64_t{0});
  for (const auto& cand : details.value("candidates", json::array())) {
    for (const auto& s : cand.value("copies", json::array())) {
      const std::int64_t cid = s.value("copy_id", std::int64_t{0});
      auto copy = st.get_copy(cid);
      if (!copy) continue;
      copy_of[cid] = *copy;
      const std::string who = customers.count(copy->customer_id) ? customers[copy->customer_id] : "";
      const double p = s.value("p_value", 1.0);
      const double nl = p > 0 ? -std::log10(p) : details.value("best_neg_log10_corrected_p", 300.0);
      json stats = json::object();
      for (const char* k : {"correlation", "compared", "sign_neg_log10_p", "binomial_neg_log10_p",
                            "calibrated_neg_log10_p", "null_mean", "null_sd", "matched_statistic",
                            "matched_neg_log10_p", "bit_error_rate", "strength"})
        if (s.contains(k)) stats[k] = s[k];
      copies.push_back({{"copy_id", cid}, {"customer", who}, {"neg_log10_corrected_p", nl},
                        {"corrected_p", p}, {"payload_matches", s.value("payload_matches", false)},
                        {"statistics", stats}});
      bars.push_back({who + " copy " + std::to_string(cid), nl});
      const double sd = s.value("null_sd", 0.0);
      const double z = sd > 0 ? (s.value("correlation", 0.0) - s.value("null_mean", 0.0)) / sd : 0.0;
      if (cid == best_copy) {
        best_z = z;
        best_label = who + " copy " + std::to_string(cid);
      } else {
        other_z.push_back(z);
      }
      copy_rows.push_back({{"id", copy->id}, {"asset_id", copy->asset_id}, {"customer_id", copy->customer_id},
                           {"key_version", copy->key_version}, {"payload_hex", copy->payload_hex},
                           {"params", parsed(copy->params_json)}, {"outputs", parsed(copy->outputs_json)},
                           {"job_id", copy->job_id ? json(*copy->job_id) : json(nullptr)},
                           {"created_at", iso_time(copy->created_at)}});
    }
  }
  records["copies"] = copy_rows;

  json attributed = json::array();
  for (const auto& a : details.value("attributed", json::array())) {
    const std::int64_t cid = a.value("copy_id", std::int64_t{0});
    json aj{{"copy_id", cid},
            {"customer_id", a.value("customer_id", std::int64_t{0})},
            {"customer", a.value("customer", "")},
            {"corrected_p", a.value("corrected_p", 1.0)},
            {"neg_log10_corrected_p", a.value("neg_log10_corrected_p", 0.0)}};
    if (copy_of.count(cid)) {
      const auto& c = copy_of[cid];
      aj["key"] = {{"customer_id", c.customer_id}, {"version", c.key_version},
                   {"id", "customer:" + std::to_string(c.customer_id) + "/key:v" + std::to_string(c.key_version)}};
      aj["issued_at"] = iso_time(c.created_at);
      aj["payload_issued"] = c.payload_hex;
    }
    if (cid == best_copy) aj["payload_decoded"] = det->decoded_payload_hex;
    attributed.push_back(aj);
  }

  // Files: the suspect and the original from the blob store; the copy issued, as recorded.
  json files = json::array();
  std::vector<Subject> referenced;
  auto add_file = [&](const std::string& role, const std::string& name, const std::string& sha,
                      const std::string& location) {
    files.push_back({{"role", role}, {"name", name}, {"sha256", sha}, {"location", location}});
    referenced.push_back({role + "/" + fs::path(name).filename().string(), sha});
  };
  add_file("suspect", det->suspect_name, det->suspect_sha256,
           st.blobs().contains(det->suspect_sha256) ? "blob store" : "");
  if (asset) add_file("original", asset->name, asset->sha256, "blob store");
  const store::IssuedCopy* issued = det->copy_id && copy_of.count(*det->copy_id) ? &copy_of[*det->copy_id] : nullptr;
  std::string decoded_path;
  if (issued) {
    const json outputs = parsed(issued->outputs_json);
    for (const auto& f : outputs.value("files", json::array())) {
      const std::string role = f.value("role", "") == "stream" ? "issued-stream" : "issued-copy";
      add_file(role, f.value("path", ""), f.value("sha256", ""), f.value("path", ""));
      if (role == "issued-copy") decoded_path = f.value("path", "");
    }
  }

  // Chain of records: the original's intake, the copy's issue, the detection, with the audit log.
  json chain = json::array();
  std::set<std::string> subjects;
  if (asset) {
    chain.push_back({{"at", iso_time(asset->created_at)}, {"actor", "store"}, {"action", "asset.intake"},
                     {"subject", "asset:" + std::to_string(asset->id)},
                     {"details", {{"name", asset->name}, {"sha256", asset->sha256}}}});
    subjects.insert("asset:" + std::to_string(asset->id));
  }
  for (const auto& [cid, c] : copy_of) {
    if (c.job_id) subjects.insert("job:" + std::to_string(*c.job_id));
    subjects.insert("customer:" + std::to_string(c.customer_id));
  }
  if (det->job_id) subjects.insert("job:" + std::to_string(*det->job_id));
  std::vector<store::AuditEntry> audit = st.list_audit(1000000);
  std::reverse(audit.begin(), audit.end());
  for (const auto& e : audit)
    if (subjects.count(e.subject))
      chain.push_back({{"at", iso_time(e.at)}, {"actor", e.actor}, {"action", e.action}, {"subject", e.subject},
                       {"details", parsed(e.details_json)}, {"audit_id", e.id}});
  chain.push_back({{"at", iso_time(det->created_at)}, {"actor", "store"}, {"action", "detection.record"},
                   {"subject", "detection:" + std::to_string(det->id)}, {"details", {{"verdict", det->verdict}}}});
  if (det->job_id)
    if (auto j = st.get_job(*det->job_id))
      records["detect_job"] = {{"id", j->id}, {"kind", j->kind}, {"payload", parsed(j->payload_json)},
                               {"attempt", j->attempt}, {"created_at", iso_time(j->created_at)},
                               {"result", parsed(j->result_json)}};
  // Each record with the SHA-256 of its JSON as listed here (before this field was added).
  for (auto& [k, v] : records.items()) {
    if (v.is_array())
      for (auto& e : v) e["record_sha256"] = sha256_of(e.dump());
    else
      v["record_sha256"] = sha256_of(v.dump());
  }

  const std::string case_id = !options.case_id.empty()
                                  ? options.case_id
                                  : "MM-" + std::to_string(det->id) + "-" + det->suspect_sha256.substr(0, 12);
  json method{{"statistic", kStatistic}, {"decision_rule", kDecisionRule},
              {"p_threshold", details.value("p_threshold", 0.0)},
              {"false_attribution", parsed(false_attribution_record_json())}};
  json predicate{{"case_id", case_id},
                 {"created_at", iso_time(st.now())},
                 {"meshmark", {{"version", meshmark_version()}, {"build_sha256", build_sha256()}}},
                 {"signer", {{"key_id", signer.public_key().id()}, {"public_key", signer.public_key().text()}}},
                 {"detection",
                  {{"id", det->id}, {"verdict", det->verdict}, {"suspect_name", det->suspect_name},
                   {"suspect_sha256", det->suspect_sha256}, {"copies_tried", details.value("copies_tried", 0)},
                   {"created_at", iso_time(det->created_at)}, {"reason", details.value("reason", "")},
                   {"resync_method", det->resync_method},
                   {"decoded_payload_hex", det->decoded_payload_hex}}},
                 {"asset", records.contains("asset") ? records["asset"] : json(nullptr)},
                 {"attributed", attributed},
                 {"copies", copies},
                 {"method", method},
                 {"chain", chain},
                 {"files", files},
                 {"configuration", details.value("parameters", json{{"p_threshold", details.value("p_threshold", 0.0)}})},
                 {"timestamp", options.tsa_url.empty()
                                   ? json{{"requested", false},
                                          {"note", "No trusted timestamp was requested: the times in this package are "
                                                   "the installation's own clock."}}
                                   : json{{"requested", true}, {"authority", options.tsa_url}, {"file", "statement.tsr"}}},
                 {"records", records}};

  // Pictures (only what is at hand: an absent or altered file is left out, and the page says so).
  std::vector<jobs::ReportPicture> pictures;
  std::string picture_note;
  try {
    if (asset && st.blobs().contains(det->suspect_sha256)) {
      // A CAD original is tessellated again as it was for the copy (the options its preparation
      // key records), not with today's configuration.
      // A 3MF original is read as the object the copy was made of.
      TessellationOptions cad;
      std::string object;
      if (issued) {
        const std::string key = jobs::copy_prepare_key(issued->params_json);
        if (auto o = tessellation_options_in(key)) cad = *o;
        object = object_of_prepare_key(key);
      }
      const Mesh original = read_named_mesh(st.blobs().get(asset->sha256), asset->name, nullptr, cad, object);
      const Mesh suspect = read_named_mesh(st.blobs().get(det->suspect_sha256), det->suspect_name);
      std::optional<Mesh> copy;
      if (!decoded_path.empty() && fs::exists(decoded_path)) {
        const std::string bytes = read_file(decoded_path);
        copy = read_named_mesh(std::vector<std::uint8_t>(bytes.begin(), bytes.end()), decoded_path);
      }
      const jobs::RegisteredSuspect reg = jobs::register_to_original(original, suspect);
      pictures.push_back(jobs::side_by_side_picture(original, copy ? &*copy : nullptr, reg.mesh));
      pictures.push_back(jobs::distance_picture(original, reg.mesh));
    }
  } catch (const std::exception& e) {
    picture_note = std::string("pictures of the meshes could not be made: ") + e.what();
  }
  if (!best_label.empty()) pictures.push_back(jobs::null_picture(best_z, other_z, best_label));
  if (!bars.empty())
    pictures.push_back(jobs::copy_scores_picture(bars, -std::log10(details.value("p_threshold", 1e-9))));
  if (!picture_note.empty()) predicate["pictures_note"] = picture_note;

  // Write beside out_dir, then rename: the package appears whole or not at all.
  const fs::path out = fs::absolute(out_dir);
  const fs::path tmp = out.parent_path() / (out.filename().string() + ".partial-" + std::to_string(::getpid()));
  fs::remove_all(tmp);
  fs::create_directories(tmp);
  EvidencePackage pkg;
  pkg.dir = out.string();
  pkg.key_id = signer.public_key().id();
  try {
    const std::string html = jobs::evidence_html(predicate, pictures);
    support::write_file_atomic((tmp / "report.html").string(), html, 0644);
    std::vector<Subject> subjects_list = {{"report.html", sha256_of(html)}};
    pkg.files.push_back("report.html");

    const std::string browser = options.chromium.empty() ? "chromium" : options.chromium;
    if (options.chromium == "none") {
      pkg.pdf_note = "no PDF requested";
    } else if (!on_path(browser)) {
      pkg.pdf_note = "no PDF: " + browser + " is not installed";
    } else {
      const fs::path profile = tmp / ".chromium-profile";
      const std::string pdf = (tmp / "report.pdf").string();
      const int rc = run_program({"timeout", "120", browser, "--headless", "--no-sandbox", "--disable-gpu",
                                  "--no-first-run", "--disable-background-networking", "--disable-component-update",
                                  "--disable-sync", "--user-data-dir=" + profile.string(), "--no-pdf-header-footer",
                                  "--print-to-pdf=" + pdf, "file://" + (tmp / "report.html").string()},
                                 (tmp / ".chromium.log").string());
      fs::remove_all(profile);
      fs::remove(tmp / ".chromium.log");
      if (rc == 0 && fs::exists(pdf) && fs::file_size(pdf) > 0) {
        subjects_list.push_back({"report.pdf", support::sha256_file_hex(pdf)});
        pkg.files.push_back("report.pdf");
      } else {
        fs::remove(pdf);
        pkg.pdf_note = "no PDF: " + browser + " exited with status " + std::to_string(rc);
      }
    }
    if (!pkg.pdf_note.empty()) predicate["pdf_note"] = pkg.pdf_note;
    for (const auto& s : referenced) subjects_list.push_back(s);

    json subject = json::array();
    for (const auto& s : subjects_list) subject.push_back({{"name", s.name}, {"digest", {{"sha256", s.sha256}}}});
    const json statement{{"_type", kStatementType}, {"subject", subject}, {"predicateType", kPredicateType},
                         {"predicate", predicate}};
    const std::string body = statement.dump(2) + "\n";
    support::write_file_atomic((tmp / "statement.json").string(), body, 0644);
    pkg.files.push_back("statement.json");
    support::write_file_atomic((tmp / "statement.dsse.json").string(), dsse_envelope(signer, body), 0644);
    pkg.files.push_back("statement.dsse.json");

    if (options.tsa_url.empty()) {
      pkg.timestamp_note = "none requested";
    } else {
      const std::string query = (tmp / ".statement.tsq").string(), reply = (tmp / "statement.tsr").string();
      const std::string log = (tmp / ".tsa.log").string();
      if (run_program({"openssl", "ts", "-query", "-data", (tmp / "statement.json").string(), "-sha256", "-cert",
                       "-out", query}, log) != 0)
        throw std::runtime_error("cannot make the timestamp query (openssl ts -query): " + read_file(log));
      if (run_program({"curl", "--silent", "--show-error", "--fail", "--max-time", "60", "-H",
                       "Content-Type: application/timestamp-query", "--data-binary", "@" + query, "-o", reply,
                       options.tsa_url}, log) != 0)
        throw std::runtime_error("time-stamping authority " + options.tsa_url + " did not answer: " + read_file(log));
      if (!options.tsa_ca_file.empty() &&
          run_program({"openssl", "ts", "-verify", "-data", (tmp / "statement.json").string(), "-in", reply,
                       "-CAfile", options.tsa_ca_file}, log) != 0)
        throw std::runtime_error("the timestamp from " + options.tsa_url + " does not verify against " +
                                 options.tsa_ca_file + ": " + read_file(log));
      fs::remove(query);
      fs::remove(log);
      pkg.files.push_back("statement.tsr");
      // The reply signed too, so that no byte of the package escapes a signature (an authority's
      // reply carries certificates its own signature does not cover).
      const std::string tsr_bytes = read_file(reply);
      const json tsr_statement{
          {"_type", kStatementType},
          {"subject", json::array({json{{"name", "statement.tsr"}, {"digest", {{"sha256", sha256_of(tsr_bytes)}}}}})},
          {"predicateType", kTimestampPredicateType},
          {"predicate", {{"statement_sha256", sha256_of(body)}, {"authority", options.tsa_url}}}};
      support::write_file_atomic((tmp / "statement.tsr.dsse.json").string(),
                                 dsse_envelope(signer, tsr_statement.dump(2) + "\n"), 0644);
      pkg.files.push_back("statement.tsr.dsse.json");
      pkg.timestamp_note = "RFC 3161 timestamp from " + options.tsa_url;
    }
    if (fs::exists(out)) fs::remove(out);  // the empty folder checked above
    fs::rename(tmp, out);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
  return pkg;
}

namespace {

// The timestamp reply: its SHA-256 as signed in statement.tsr.dsse.json, then the reply itself
// against the authority's CA certificate when one is given.
void check_timestamp(const fs::path& d, const std::vector<keys::PublicKey>& trusted, const std::string& tsa_ca_file,
                     VerifyReport& r) {
  const std::string tsr = (d / "statement.tsr").string();
  if (!fs::exists(tsr)) {
    r.failed.push_back("statement.tsr: the statement says a timestamp was requested, but it is missing");
    return;
  }
  const OpenedEnvelope te = open_envelope(d / "statement.tsr.dsse.json", trusted);
  const json ts = json::parse(te.body.empty() ? "null" : te.body, nullptr, false);
  std::string want;
  if (ts.is_object() && ts.value("predicateType", "") == kTimestampPredicateType && !ts["subject"].empty())
    want = ts["subject"][0].value("digest", json::object()).value("sha256", "");
  if (!te.error.empty())
    r.failed.push_back(te.error);
  else if (want != support::sha256_file_hex(tsr))
    r.failed.push_back("statement.tsr: SHA-256 differs from the signed record of it (the file was altered)");
  else
    r.passed.push_back("statement.tsr: SHA-256 matches its signed record");
  if (tsa_ca_file.empty()) {
    r.skipped.push_back("statement.tsr: present; its authority not checked (give the authority's CA certificate)");
    return;
  }
  const std::string log =
      (fs::temp_directory_path() / ("meshmark-verify-" + std::to_string(::getpid()) + ".log")).string();
  const int rc = run_program(
      {"openssl", "ts", "-verify", "-data", (d / "statement.json").string(), "-in", tsr, "-CAfile", tsa_ca_file}, log);
  std::string when;
  if (rc == 0 && run_program({"openssl", "ts", "-reply", "-in", tsr, "-text"}, log) == 0) {
    std::istringstream text(read_file(log));
    for (std::string line; std::getline(text, line);)
      if (line.rfind("Time stamp: ", 0) == 0) when = " (time " + line.substr(12) + ")";
  }
  std::error_code ec;
  fs::remove(log, ec);
  if (rc == 0)
    r.passed.push_back("statement.tsr: RFC 3161 timestamp of statement.json verifies against " + tsa_ca_file + when);
  else
    r.failed.push_back("statement.tsr: the timestamp does not verify for statement.json against " + tsa_ca_file);
}

}  // namespace

VerifyReport verify_evidence_package(const std::string& dir, const std::vector<keys::PublicKey>& trusted,
                                     const std::vector<std::string>& referenced, const store::BlobStore* blobs,
                                     const std::string& tsa_ca_file) {
  VerifyReport r;
  const fs::path d(dir);
  const OpenedEnvelope env = open_envelope(d / "statement.dsse.json", trusted);
  if (env.body.empty()) {
    r.failed.push_back(env.error);
    return r;
  }
  const std::string& body = env.body;
  if (env.error.empty())
    r.passed.push_back("signature: valid, by trusted key " + env.signer);
  else
    r.failed.push_back("signature: " + env.error);

  std::string on_disk;
  try {
    on_disk = read_file((d / "statement.json").string());
  } catch (const std::exception&) {
    r.failed.push_back("statement.json: missing");
  }
  if (!on_disk.empty()) {
    if (on_disk == body)
      r.passed.push_back("statement.json: identical to the signed statement");
    else
      r.failed.push_back("statement.json: differs from the signed statement in statement.dsse.json");
  }
  json statement = json::parse(body, nullptr, false);
  if (statement.is_discarded() || statement.value("_type", "") != kStatementType ||
      statement.value("predicateType", "") != kPredicateType) {
    r.failed.push_back("statement: not an in-toto v1 statement of meshmark detection evidence");
    return r;
  }

  // Subjects: package files must be present and match; referenced files are checked when at hand.
  std::map<std::string, std::string> at_hand;  // digest -> path
  for (const auto& p : referenced) {
    try {
      at_hand[support::sha256_file_hex(p)] = p;
    } catch (const std::exception&) {
      r.failed.push_back(p + ": cannot read");
    }
  }
  std::map<std::string, std::string> location;  // "role/name" -> recorded location
  for (const auto& f : statement["predicate"].value("files", json::array()))
    location[f.value("role", "") + "/" + fs::path(f.value("name", "")).filename().string()] = f.value("location", "");
  std::set<std::string> listed = {"statement.json", "statement.dsse.json"};
  if (statement["predicate"].value("timestamp", json::object()).value("requested", false)) {
    listed.insert("statement.tsr");
    listed.insert("statement.tsr.dsse.json");
  }
  for (const auto& s : statement.value("subject", json::array())) {
    const std::string name = s.value("name", "");
    const std::string want = s.value("digest", json::object()).value("sha256", "");
    if (name.find('/') == std::string::npos) {
      listed.insert(name);
      if (!fs::exists(d / name)) {
        r.failed.push_back(name + ": missing from the package");
      } else if (support::sha256_file_hex((d / name).string()) != want) {
        r.failed.push_back(name + ": SHA-256 differs from the statement's (the file was altered)");
      } else {
        r.passed.push_back(name + ": SHA-256 matches");
      }
      continue;
    }
    if (at_hand.count(want)) {
      r.passed.push_back(name + ": " + at_hand[want] + " matches its SHA-256");
    } else if (blobs && blobs->contains(want)) {
      try {
        blobs->get(want);  // verifies the content against the address
        r.passed.push_back(name + ": in the blob store, SHA-256 matches");
      } catch (const std::exception& e) {
        r.failed.push_back(name + ": the blob store's copy is corrupted: " + e.what());
      }
    } else if (location.count(name) && !location[name].empty() && location[name] != "blob store" &&
               fs::exists(location[name])) {
      if (support::sha256_file_hex(location[name]) == want)
        r.passed.push_back(name + ": " + location[name] + " matches its SHA-256");
      else
        r.failed.push_back(name + ": " + location[name] + " differs from the SHA-256 recorded (the file was altered)");
    } else {
      r.skipped.push_back(name + ": not at hand (give the file to check it)");
    }
  }
  for (const auto& e : fs::directory_iterator(d))
    if (!listed.count(e.path().filename().string()))
      r.failed.push_back(e.path().filename().string() + ": in the package but not in the signed statement");

  if (listed.count("statement.tsr")) check_timestamp(d, trusted, tsa_ca_file, r);
  return r;
}

}  // namespace mm::service
