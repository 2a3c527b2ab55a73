#include "jobs/detect_suspect.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <tuple>
#include <nlohmann/json.hpp>

#include "jobs/payload.h"
#include "meshio/normalize.h"

namespace mm::jobs {

namespace {

using nlohmann::json;

// Shares of a suspect's points an asset's footprint must hold for the asset to be a candidate:
// within a cell of its surface (cut faces or stray points may leave a few outside), and in the
// surface's own cells (a suspect moved into another part's box lands near its cells by chance:
// about half in the shared parts' measurements, docs/daemon.md).
constexpr double kCoveredNear = 0.9;
constexpr double kCoveredExact = 0.6;
// Covering assets whose region agreement is this close to the best one's are all tried, up to
// kMaxTied: a crop of one of several parts that share that region matches each of them.
constexpr double kAgreementTie = 0.05;
constexpr int kMaxTied = 12;

// What a polyhedron row keeps of the original's shape (either may be absent: rows written before
// footprints were kept have none).
struct AssetShape {
  std::optional<ShapeSignature> signature;
  std::optional<SurfaceFootprint> footprint;
};

// One shape per polyhedron the asset's copies were made from: a change of compression options
// gives the same shape again, but each object of a 3MF build has its own.
std::vector<AssetShape> asset_shapes(DetectionStore& st, std::int64_t asset_id,
                                     const std::vector<IssuedCopyRecord>& copies, std::vector<std::string>* warnings) {
  std::vector<AssetShape> shapes;
  std::set<std::string> keys;
  for (const auto& c : copies) {
    const std::string key = copy_prepare_key(c.params_json);
    if (!keys.insert(key).second) continue;
    auto row = st.polyhedron(asset_id, key);
    if (!row) continue;
    try {
      AssetShape shape;
      const json meta = json::parse(row->meta_json);
      shape.signature = ShapeSignature::from_json(meta.at("signature").dump());
      if (meta.contains("footprint")) shape.footprint = SurfaceFootprint::from_json(meta.at("footprint").dump());
      shapes.push_back(std::move(shape));
    } catch (const std::exception& e) {
      warnings->push_back("asset " + std::to_string(asset_id) + ": no usable shape signature: " + e.what());
    }
  }
  return shapes;
}

// Candidate assets in the order they are tried, and how they were found. Without a hash or
// stream match: the assets whose surface, in their own units, holds nearly all of the suspect
// (a copy as issued, or a piece cut from one), best covered first; when none does, those whose
// shape signature resembles the suspect's (a moved, rescaled or re-tessellated whole copy).
std::vector<std::int64_t> candidate_assets(DetectionStore& st, const Suspect& suspect,
                                           const std::map<std::int64_t, std::vector<IssuedCopyRecord>>& copies_of,
                                           int max_candidates, std::string* match,
                                           std::map<std::int64_t, double>* agreement,
                                           std::vector<std::string>* warnings) {
  std::vector<std::int64_t> candidates;
  auto add = [&](std::int64_t id) {
    if (std::find(candidates.begin(), candidates.end(), id) == candidates.end()) candidates.push_back(id);
  };
  for (const auto& [asset_id, copies] : copies_of)
    for (const auto& c : copies) {
      try {
        for (const auto& f : json::parse(c.outputs_json).value("files", json::array()))
          if (f.value("sha256", "") == suspect.sha256) {
            add(asset_id);
            if (match->empty())
              *match = "hash of issued copy " + std::to_string(c.id) + " (" + f.value("role", "decoded") + ")";
          }
      } catch (const json::exception&) {
      }
    }
  if (auto a = st.asset_with_sha256(suspect.sha256)) {
    add(*a);
    if (match->empty()) *match = "hash of original asset " + std::to_string(*a);
  }
  auto named = suspect.stream_metadata.find("asset");
  if (candidates.empty() && named != suspect.stream_metadata.end())
    if (auto a = st.asset_with_sha256(named->second)) add(*a), *match = "stream metadata";
  if (candidates.empty()) {
    const ShapeSignature sig = shape_signature(suspect.mesh);
    const FootprintProbe probe = footprint_probe(suspect.mesh);
    std::vector<std::tuple<double, double, std::int64_t>> covering;  // -agreement, -exact, asset
    std::vector<std::pair<double, std::int64_t>> resembling;
    for (const auto& [asset_id, copies] : copies_of) {
      std::optional<std::pair<double, double>> held;  // the best (agreement, exact) of its shapes
      std::optional<double> nearest;
      for (const AssetShape& shape : asset_shapes(st, asset_id, copies, warnings)) {
        if (shape.footprint && covered_fraction(*shape.footprint, probe) >= kCoveredNear) {
          const double exact = covered_fraction(*shape.footprint, probe, 0);
          if (exact >= kCoveredExact) {
            const std::pair<double, double> score{region_agreement(*shape.footprint, suspect.mesh), exact};
            if (!held || score > *held) held = score;
          }
        }
        if (shape.signature) {
          const double d = signature_distance(sig, *shape.signature);
          if (d < 0.5 && (!nearest || d < *nearest)) nearest = d;
        }
      }
      if (held) covering.push_back({-held->first, -held->second, asset_id});
      if (nearest) resembling.push_back({*nearest, asset_id});
    }
    std::sort(covering.begin(), covering.end());
    std::sort(resembling.begin(), resembling.end());
    if (!covering.empty()) {
      // The best max_candidates, and every further one as alike over the suspect's region as the
      // best (within kAgreementTie): parts identical there differ only in their marks.
      const double best = -std::get<0>(covering.front());
      for (const auto& [neg_a, neg_exact, id] : covering) {
        const int n = static_cast<int>(candidates.size());
        if (n < max_candidates || (-neg_a >= best - kAgreementTie && n < kMaxTied)) {
          add(id);
          (*agreement)[id] = -neg_a;
        }
      }
      *match = "surface footprint";
    } else {
      for (const auto& r : resembling)
        if (static_cast<int>(candidates.size()) < max_candidates) add(r.second);
      if (!candidates.empty()) *match = "shape signature";
    }
  }
  return candidates;
}

std::vector<CopyCandidate> copy_candidates(DetectionStore& st, const std::vector<IssuedCopyRecord>& copies) {
  std::vector<CopyCandidate> cands;
  for (const auto& c : copies) {
    CopyCandidate cc;
    cc.copy_id = c.id;
    if (c.nonce.size() != cc.nonce.size()) continue;
    std::copy(c.nonce.begin(), c.nonce.end(), cc.nonce.begin());
    try {
      cc.payload = parse_payload_hex(c.payload_hex);
      cc.settings = copy_settings(c.params_json);
    } catch (const std::exception&) {
      continue;
    }
    cc.key = st.customer_key(c.customer_id, c.key_version);
    cands.push_back(cc);
  }
  return cands;
}

void decide(Detection& d, double p_threshold) {
  if (d.candidates.empty()) {
    d.verdict = "unknown asset";
    return;
  }
  for (int t = 0; t < static_cast<int>(d.tried.size()); ++t)
    for (auto& s : d.tried[static_cast<std::size_t>(t)].scores) {
      s.corrected_p = corrected_p(s.p_value, d.copies_tried);
      if (!d.best || better_copy(s, *d.best)) d.best = s, d.best_tried = t;
    }
  if (!d.best) {
    d.verdict = "no watermark found";
    d.asset_id = d.candidates.front();
    return;
  }
  const CopyScore& best = *d.best;
  const PolyhedronTried& where = d.tried[static_cast<std::size_t>(d.best_tried)];
  d.asset_id = where.asset_id;
  d.best_neg_log10_corrected_p = std::max(0.0, best.neg_log10_p - std::log10(std::max(1, d.copies_tried)));
  int bits = 32;
  for (const auto& c : where.copies)
    if (c.id == best.copy_id) {
      bits = static_cast<int>(c.payload_hex.size()) * 4;
      switch (finding_of(best.corrected_p, p_threshold, best.payload_matches)) {
        case Finding::present:
          d.verdict = "attributed";
          d.copy_id = c.id;
          d.customer_id = c.customer_id;
          break;
        case Finding::inconclusive:
          d.verdict = "inconclusive";
          d.reason = inconclusive_reason("copy " + std::to_string(c.id), "corrected p", best.corrected_p,
                                         p_threshold, best.payload_matches);
          break;
        case Finding::absent:
          break;
      }
    }
  d.decoded_payload_hex = payload_hex(best.decoded_payload, bits);
  if (d.verdict == "attributed")
    for (const auto& t : d.tried)
      for (const auto& s : t.scores)
        if (s.corrected_p < p_threshold)
          for (const auto& c : t.copies)
            if (c.id == s.copy_id)
              d.attributed.push_back({c.id, c.customer_id, s.corrected_p,
                                      std::max(0.0, s.neg_log10_p - std::log10(std::max(1, d.copies_tried)))});
  std::stable_sort(d.attributed.begin(), d.attributed.end(),
                   [](const Detection::Attributed& a, const Detection::Attributed& b) {
                     return a.neg_log10_corrected_p > b.neg_log10_corrected_p;
                   });
  if (d.verdict.empty()) d.verdict = "no watermark found";
}

}  // namespace

std::string copy_params_json(const WatermarkSettings& s, const std::string& prepare_key,
                             const std::string& basis_sha256) {
  return json{{"method", method_name(s.params.method)},
              {"strength", s.params.strength},
              {"threshold", s.params.threshold},
              {"message_bits", s.message_bits},
              {"prepare", prepare_key},
              {"basis_sha256", basis_sha256}}
      .dump();
}

WatermarkSettings copy_settings(const std::string& params_json) {
  const json j = json::parse(params_json);
  WatermarkSettings s;
  s.params.method = method_from_name(j.at("method").get<std::string>());
  s.params.strength = j.at("strength").get<double>();
  s.params.threshold = j.at("threshold").get<double>();
  s.message_bits = j.at("message_bits").get<int>();
  return s;
}

std::string copy_prepare_key(const std::string& params_json) {
  try {
    return json::parse(params_json).value("prepare", "");
  } catch (const json::exception&) {
    return "";
  }
}

Alignment align_suspect(const PreparedAsset& asset, const std::string& polyhedron_blob, const Mesh& suspect,
                        const std::string& name, const ContextSource& contexts) {
  Alignment a;
  try {
    // Building a context costs more than a detection, so callers may keep them, keyed by the
    // polyhedron's content address (a blob never changes).
    auto build = [&asset] { return make_resync_context(asset); };
    std::shared_ptr<const ResyncContext> ctx =
        contexts ? contexts(polyhedron_blob, build) : std::make_shared<const ResyncContext>(build());
    ResyncOptions o;
    o.source = name;
    // Copies are issued in the part's units (protect undoes the normalisation), so a copy leaked
    // as issued lies in the asset's frame once normalised, where the unmoved pairing explains it
    // exactly; aligned by a fitted similarity instead, a part symmetric about an axis may settle
    // on a symmetric pose (abc7's issued STL copies were paired exactly but permuted).
    Mesh in_frame = suspect;
    apply(asset.normalization, in_frame.points);
    Resynchronized r = resynchronize_suspect(*ctx, in_frame, o);
    for (int l = 0; l <= ctx->max_level(); ++l) a.levels_built += ctx->level_built(l) ? std::to_string(l) : "-";
    a.context_mb = static_cast<double>(ctx->memory_bytes()) / (1 << 20);
    a.points = std::move(r.points);
    a.method = r.method;
    a.level = r.level;
    a.residual = r.residual_rms;
    a.matched_fraction = r.matched_fraction;
    a.attack_model = r.attack_model;
    a.readings = suspect_readings(*ctx, in_frame, r);
  } catch (const InputError& e) {  // this candidate does not fit; others may
    a.method = std::string("none: ") + e.reason();
  }
  return a;
}

Detection detect_suspect(DetectionStore& st, const Suspect& suspect, const DetectOptions& options) {
  std::map<std::int64_t, std::vector<IssuedCopyRecord>> copies_of;
  for (auto& c : st.issued_copies()) copies_of[c.asset_id].push_back(std::move(c));

  Detection d;
  d.candidates = candidate_assets(st, suspect, copies_of, options.max_candidates, &d.match, &d.region_agreement,
                                  &d.warnings);

  // Every copy ever issued for a candidate, grouped by the polyhedron it was embedded in (a
  // change of compression options gives later copies another polyhedron).
  for (std::int64_t asset_id : d.candidates) {
    std::map<std::string, std::vector<IssuedCopyRecord>> groups;
    for (const auto& c : copies_of[asset_id]) groups[copy_prepare_key(c.params_json)].push_back(c);
    for (auto& [key, copies] : groups) {
      auto row = st.polyhedron(asset_id, key);
      if (!row) {
        d.warnings.push_back("asset " + std::to_string(asset_id) + ": " + std::to_string(copies.size()) +
                             " copies name a polyhedron that is not cached (\"" + key + "\")");
        continue;
      }
      PreparedAsset prep = decode_prepared(st.blob(row->polyhedron_blob), st.blob(row->basis_blob),
                                           "asset " + std::to_string(asset_id) + " polyhedron " +
                                               std::to_string(row->id));
      PolyhedronTried t;
      t.asset_id = asset_id;
      t.polyhedron_id = row->id;
      t.alignment = align_suspect(prep, row->polyhedron_blob, suspect.mesh, suspect.name, options.contexts);
      t.copies = std::move(copies);
      const std::vector<CopyCandidate> cands = copy_candidates(st, t.copies);
      if (std::isfinite(t.alignment.residual) && prep.control.num_vertices() == t.alignment.points.rows())
        t.scores = score_copies(prep, t.alignment.points, cands, &t.alignment.readings);
      d.copies_tried += static_cast<int>(t.scores.size());
      d.tried.push_back(std::move(t));
    }
  }
  decide(d, options.p_threshold);
  return d;
}

}  // namespace mm::jobs
