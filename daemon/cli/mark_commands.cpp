// embed and extract: the watermark half of the offline CLI, on files only.
//   meshmark embed ORIGINAL KEY OUT -m TEXT     one customer's watermarked copy + OUT.mmrec.json
//   meshmark extract ORIGINAL SUSPECT KEY -r REC   non-blind extraction after resynchronisation
//
// The mark lives in the spectrum of the control polyhedron: a mesh ORIGINAL is used as the
// polyhedron itself, a .mmc ORIGINAL contributes its decoded polyhedron. Everything is computed in
// the original's unit box (the paper's frame) and mapped back to the part's units for output.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli/commands.h"
#include "cli/copy_record.h"
#include "cli/file_util.h"
#include "cli/key_file.h"
#include "cli/mesh_files.h"
#include "codec/stream.h"
#include "jobs/detect.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"
#include "registration/resynchronize.h"
#include "spectral/spectral_basis.h"
#include "subdivision/decompress.h"
#include "watermark/matched_score.h"
#include "watermark/null_calibration.h"
#include "watermark/watermark.h"

#ifndef MESHMARK_VERSION
#define MESHMARK_VERSION "unknown"
#endif

namespace mm::cli {
namespace {

// "watermark present" needs the p-value below this AND the recorded message decoded exactly.
constexpr double kPresentP = 1e-9;
// Every message bit must get at least this many coefficient copies (r >= 4).
constexpr int kMinRepeat = 4;
// The quantised stream copy must keep this correlation (and the whole message) for `embed` to
// accept a quantisation.
constexpr double kStreamMinCorrelation = 0.95;

// The original's control polyhedron in its unit box, with the basis the mark lives in.
struct Control {
  InputFile file;
  Normalization norm;
  Mesh normalized;
  SpectralBasis basis;
};

Control load_control(const std::string& path) {
  Control c;
  c.file = load_input(path);
  const Mesh& m = c.file.mesh;
  if (m.num_vertices() > kMaxBasisVertices)
    throw InputError(path, "has " + std::to_string(m.num_vertices()) + " control vertices; the spectral basis is limited to " +
                               std::to_string(kMaxBasisVertices) + " (compress it first: meshmark compress)");
  c.norm = unit_box_normalization(m.points);
  if (!(std::isfinite(c.norm.scale) && c.norm.scale > 0))
    throw InputError(path, "degenerate bounding box (all vertices coincide)");
  c.normalized = m;
  apply(c.norm, c.normalized.points);
  try {
    c.basis = compute_basis(c.normalized);
  } catch (const InputError& e) {
    throw InputError(path, e.reason());
  }
  return c;
}

bool same_file(const std::string& a, const std::string& b) {
  std::error_code ec;
  return std::filesystem::equivalent(a, b, ec);
}

Key read_key(const std::string& path) {
  const Key key = read_key_file(path);
  if (key_file_exposed(path))
    std::cerr << "meshmark: warning: " << path << " is accessible to group or others; keep keys in mode 0600\n";
  return key;
}

// Extraction of a quantised stream copy against the unmarked control, both in the unit box.
Extraction check_stream(const Control& c, const std::vector<std::uint8_t>& bytes, const std::string& out,
                        const std::vector<bool>& message, const Key& key, const Nonce& nonce,
                        const EmbedParams& params) {
  Points decoded = decode(bytes, out).mesh.points;
  apply(c.norm, decoded);
  return extract(c.basis, c.normalized.points, decoded, static_cast<int>(message.size()), key, nonce,
                 params, &message);
}

void add_embed_command(CLI::App& app) {
  struct Args {
    std::string original, key, out, message;
    int method = 2;
    double strength = 0.01, threshold = 0.05;
    int level = -1, bits = 0;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand(
      "embed", "Watermark ORIGINAL for one key holder; writes OUT and the copy record OUT.mmrec.json");
  c->add_option("original", a->original,
                "mesh (used as the control polyhedron itself) or .mmc stream (its control polyhedron is marked)")
      ->required();
  c->add_option("key", a->key, "customer key file (meshmark keygen)")->required();
  c->add_option("output", a->out,
                "by extension: .mmc the marked stream; .off/.obj/.ply/.stl the marked polyhedron, or with "
                "--level the subdivided surface")
      ->required();
  c->add_option("-m,--message", a->message,
                "text to hide: 1.." + std::to_string(kMaxMessageBytes) + " bytes of UTF-8 (8 bits per byte)")
      ->required();
  c->add_option("--method", a->method, "1: multiplicative, eq. (8); 2: additive below T, eq. (9); 3: uniform, every coefficient by T a")
      ->capture_default_str()->check(CLI::IsMember({1, 2, 3}));
  c->add_option("-a,--strength", a->strength, "strength a, in (0, 1)")
      ->capture_default_str()->check(CLI::Range(1e-9, 0.999999))->check(kFiniteNumber);
  c->add_option("-T,--threshold", a->threshold, "method 2: coefficients with |Cs| < T move by T a; method 3: all do (unit-box units)")
      ->capture_default_str()->check(CLI::Range(0.0, 10.0))->check(kFiniteNumber);
  c->add_option("--level", a->level, "mesh OUT: write the watermarked surface subdivided L times")
      ->check(CLI::Range(0, 5));
  c->add_option("--bits", a->bits,
                ".mmc OUT: quantisation bits (default: the fewest from 12, or the original stream's, "
                "that keep the whole message and correlation >= 0.95)")
      ->check(CLI::Range(kMinQuantBits, kMaxQuantBits));
  c->footer(
      "Deterministic: the per-copy nonce is derived from the key, the original's hash, the parameters and "
      "the message, so the same command gives the same bytes. Exit 1: refused; 2: bad file; see docs/cli.md.");
  c->callback([a] {
    const bool stream_out = is_stream_path(a->out);
    if (!stream_out && !is_mesh_path(a->out))
      throw CLI::ValidationError("output", a->out + ": unknown type (expected .mmc, .off, .obj, .ply or .stl)");
    if (stream_out && a->level >= 0) throw CLI::ValidationError("--level", "applies to mesh outputs only");
    if (!stream_out && a->bits > 0) throw CLI::ValidationError("--bits", "applies to .mmc outputs only");
    if (a->message.empty() || a->message.size() > static_cast<std::size_t>(kMaxMessageBytes))
      throw CLI::ValidationError("--message", "must be 1.." + std::to_string(kMaxMessageBytes) + " bytes");
    if (!valid_utf8(a->message)) throw CLI::ValidationError("--message", "is not valid UTF-8");
    if (same_file(a->out, a->original) || same_file(a->out, a->key))
      throw CommandFailed(1, a->out + ": is the original or the key file; refusing to overwrite it");

    EmbedParams params;
    params.method = static_cast<Method>(a->method);
    params.strength = a->strength;
    params.threshold = a->threshold;
    const std::vector<bool> message = message_to_bits(a->message);

    Control ctl = load_control(a->original);
    const Key key = read_key(a->key);
    const int usable = usable_coefficients(ctl.basis);
    if (usable < kMinRepeat * static_cast<int>(message.size()))
      throw InputError(a->original, "its control polyhedron has " + std::to_string(usable) +
                                        " usable spectral coefficients, too few for a " +
                                        std::to_string(message.size()) + "-bit message (" +
                                        std::to_string(kMinRepeat) + " copies per bit); shorten the message");
    const Nonce nonce = derive_nonce(key, ctl.file.sha256, params, a->message);
    Mesh marked = ctl.file.mesh;
    marked.points = embed(ctl.basis, ctl.normalized.points, message, key, nonce, params);
    undo(ctl.norm, marked.points);

    CopyRecord rec;
    rec.meshmark_version = MESHMARK_VERSION;
    rec.original_file = a->original;
    rec.original_sha256 = ctl.file.sha256;
    rec.original_kind = ctl.file.stream ? "stream" : "mesh";
    rec.control_vertices = ctl.file.mesh.num_vertices();
    rec.control_faces = ctl.file.mesh.num_faces();
    rec.basis_fingerprint = basis_fingerprint(ctl.basis);
    rec.params = params;
    rec.message = a->message;
    rec.message_bits = static_cast<int>(message.size());
    rec.nonce = nonce;
    rec.key_fingerprint = key_fingerprint(key);
    rec.output_file = a->out;

    std::string summary;
    if (stream_out) {
      CodecParams cp;
      // Only the fitted level travels on; nothing secret or customer-identifying goes in a stream.
      if (auto it = ctl.file.metadata.find("levels"); it != ctl.file.metadata.end()) cp.metadata["levels"] = it->second;
      const int first = a->bits > 0 ? a->bits : std::max(12, ctl.file.stream ? ctl.file.quant_bits : 12);
      const int last = a->bits > 0 ? a->bits : kMaxQuantBits;
      std::vector<std::uint8_t> bytes;
      Extraction check;
      for (cp.quant_bits = first; cp.quant_bits <= last; ++cp.quant_bits) {
        try {
          bytes = encode(marked, cp);
        } catch (const InputError& e) {
          throw InputError(a->original, "cannot be written as a stream: " + e.reason());
        }
        check = check_stream(ctl, bytes, a->out, message, key, nonce, params);
        if (check.bit_error_rate == 0 && check.correlation >= kStreamMinCorrelation) break;
      }
      if (cp.quant_bits > last) {
        std::ostringstream why;
        why << a->out << ": quantisation to " << last << " bits would damage the mark (correlation "
            << check.correlation << ", bit error rate " << check.bit_error_rate << "); "
            << (a->bits > 0 ? "use more --bits or omit it" : "use a larger strength");
        throw CommandFailed(1, why.str());
      }
      write_stream_file(a->out, bytes);
      rec.output_kind = "stream";
      rec.output_quant_bits = cp.quant_bits;
      rec.output_check_correlation = check.correlation;
      summary = "watermarked stream, " + std::to_string(cp.quant_bits) + "-bit quantisation, " +
                std::to_string(bytes.size()) + " bytes";
    } else if (a->level >= 0) {
      Mesh surface;
      try {
        surface = decompress_to_level(marked, a->level);
      } catch (const InputError& e) {
        throw InputError(a->original, "cannot subdivide its control polyhedron: " + e.reason());
      }
      write_mesh(surface, a->out);
      rec.output_kind = "subdivided";
      rec.output_level = a->level;
      summary = "watermarked surface at level " + std::to_string(a->level) + ", " +
                std::to_string(surface.num_vertices()) + " vertices";
    } else {
      write_mesh(marked, a->out);
      rec.output_kind = "polyhedron";
      summary = "watermarked polyhedron, " + std::to_string(marked.num_vertices()) + " vertices";
    }
    const std::string rec_path = a->out + ".mmrec.json";
    try {
      rec.output_sha256 = sha256_file_hex(a->out);
      write_file_atomic(rec_path, record_to_json(rec), 0644);
    } catch (...) {
      std::filesystem::remove(a->out);  // an output without its record could never be traced
      throw;
    }
    std::cout << a->out << ": " << summary << "; " << message.size() << "-bit message x "
              << usable / static_cast<int>(message.size()) << " copies, method " << a->method << "\n"
              << rec_path << ": copy record\n";
  });
}

// RMS per-vertex length of the displacement the mark makes (unit box): every marked coefficient
// moves by coefficient_move() (a |Cs| or T a), and W is orthonormal. Depends on the original and
// the parameters only, never on the key, so decisions based on it cannot favour a detection.
double mark_rms(const Control& c, int message_bits, const EmbedParams& p) {
  const Points cs = to_spectral(c.basis, c.normalized.points);
  const int usable = usable_coefficients(c.basis);
  const int marked = usable / message_bits * message_bits;
  double sum = 0;
  for (int j = 0; j < marked; ++j) {
    const double v = cs(c.basis.num_components + j / 3, j % 3);
    const double move = coefficient_move(p, v).size;
    sum += move * move;
  }
  return std::sqrt(sum / c.normalized.num_vertices());
}

double rms_displacement(const Similarity& t, const Points& points) {
  return std::sqrt((t.apply(points) - points).rowwise().squaredNorm().mean());
}

// Resynchronises with a fitted similarity. When vertices corresponded by index and that
// similarity moves the original less than twice the mark's own RMS displacement, it cannot be
// told apart from the mark's projection on scale, rotation and shift, and fitting it would only
// eat into the mark (an unattacked copy would lose sign agreements): such a suspect is taken as
// already in the original's frame. Nearest-neighbour matching and surface fitting keep their
// alignment, which is part of how they pair points.
Resynchronized resync(const ResyncContext& ctx, const Control& c, const Mesh& suspect, ResyncOptions opts,
                      double mark, bool& aligned) {
  opts.align = true;
  Resynchronized r = resynchronize(ctx, suspect, opts);
  aligned = r.order_recovered || r.method == "surface-fit" ||
            rms_displacement(r.to_control_frame, c.normalized.points) > 2 * mark;
  if (aligned) return r;
  opts.align = false;
  return resynchronize(ctx, suspect, opts);
}

// The daemon's rule (jobs::finding_of) in the offline command's words.
std::string verdict_for(double p, bool message_matches) {
  switch (jobs::finding_of(p, kPresentP, message_matches)) {
    case jobs::Finding::present:
      return "watermark present";
    case jobs::Finding::inconclusive:
      return "inconclusive";
    case jobs::Finding::absent:
      break;
  }
  return "no watermark found";
}

void add_extract_command(CLI::App& app) {
  struct Args {
    std::string original, suspect, key, record;
    int max_level = 4;
    bool json = false;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand(
      "extract", "Non-blind extraction: does SUSPECT carry the mark described by a copy record?");
  c->add_option("original", a->original, "the unmarked original given to embed (mesh or .mmc)")->required();
  c->add_option("suspect", a->suspect,
                "mesh or .mmc: the marked polyhedron or stream, its subdivided surface, or a noisy, "
                "remeshed, rescaled version")
      ->required();
  c->add_option("key", a->key, "the key file the record was made with")->required();
  c->add_option("-r,--record", a->record, "copy record written by embed (OUT.mmrec.json)")->required();
  c->add_option("--max-level", a->max_level, "highest subdivision level recognised when resynchronising")
      ->capture_default_str()->check(CLI::Range(0, 6));
  c->add_flag("--json", a->json, "print the result as JSON");
  c->footer(
      "Verdict: \"watermark present\" when p < 1e-9 (the decoded message is reported beside it), "
      "\"inconclusive\" when only one holds, else \"no watermark found\"; exit 0 whatever the verdict. "
      "Exit 1: record for another original or key; 2: bad file; 3: basis differs from the record. See docs/cli.md.");
  c->callback([a] {
    const auto rec_bytes = read_file_bytes(a->record);
    const CopyRecord rec = record_from_json(std::string(rec_bytes.begin(), rec_bytes.end()), a->record);
    Control ctl = load_control(a->original);
    if (ctl.file.sha256 != rec.original_sha256)
      throw CommandFailed(1, a->record + ": was made for another original (sha256 " + rec.original_sha256.substr(0, 16) +
                                 "..., " + a->original + " has " + ctl.file.sha256.substr(0, 16) + "...)");
    const Key key = read_key(a->key);
    if (key_fingerprint(key) != rec.key_fingerprint)
      throw CommandFailed(1, a->key + ": is not the key " + a->record + " was made with (key fingerprints differ)");
    if (basis_fingerprint(ctl.basis) != rec.basis_fingerprint)
      throw CommandFailed(3, a->original + ": its spectral basis differs from the one recorded in " + a->record +
                                 " (another build or platform?); extraction would be unreliable");

    const InputFile suspect_file = load_input(a->suspect);
    Mesh suspect = suspect_file.mesh;
    apply(ctl.norm, suspect.points);  // the original's frame, not the suspect's own (noise moves that)
    const ResyncContext ctx(ctl.normalized, a->max_level);
    ResyncOptions opts;
    opts.source = a->suspect;
    opts.max_level = a->max_level;
    bool aligned = false;
    const double mark = mark_rms(ctl, rec.message_bits, rec.params);
    const Resynchronized rs = resync(ctx, ctl, suspect, opts, mark, aligned);
    const jobs::SuspectReadings readings = jobs::suspect_readings(ctx, suspect, rs);

    const std::vector<bool> expected = message_to_bits(rec.message);
    // Scored as the daemon scores a copy (jobs::copy_statistics): the sign count with its
    // calibrated null, the matched score, the verdict on the smaller p of the two, doubled.
    const jobs::SuspectEvidence evidence = jobs::suspect_evidence(ctl.basis, ctl.normalized.points, rs.points,
                                                                  &readings, rec.message_bits, rec.params);
    const jobs::CopyStatistics st = jobs::copy_statistics(ctl.basis, evidence, key, rec.nonce, rec.params, expected);
    const Extraction& ex = st.sign;
    const NullCalibration& cal = st.calibration;
    const jobs::MarkP& sign_p = st.sign_p;
    const MatchedScore& matched = st.matched;
    const jobs::MarkP& mark_p = st.p;
    const std::vector<bool>& message = st.message;
    const bool matches = message == expected;
    const std::string decoded = bits_to_bytes(message);
    const double verdict_p = mark_p.p;
    const std::string verdict = verdict_for(verdict_p, matches);
    int wrong_bits = 0;
    for (std::size_t i = 0; i < expected.size(); ++i) wrong_bits += message[i] != expected[i];
    const std::string reason = jobs::inconclusive_reason("the copy", "p", verdict_p, kPresentP, matches);

    using nlohmann::ordered_json;
    ordered_json j{
        {"original", a->original},
        {"suspect", a->suspect},
        {"suspect_sha256", suspect_file.sha256},
        {"suspect_is_issued_file", suspect_file.sha256 == rec.output_sha256},
        {"record", a->record},
        {"resync",
         {{"method", rs.method},
          {"level", rs.level},
          {"residual_rms", rs.residual_rms},
          {"matched_fraction", rs.matched_fraction},
          {"order_recovered", rs.order_recovered},
          {"resubdivided", rs.resubdivided},
          {"aligned", aligned},
          {"scale", rs.to_control_frame.scale},
          {"mark_rms", mark}}},
        {"correlation", ex.correlation},
        {"agreements", ex.agreements},
        {"compared", ex.compared},
        {"p_value", ex.p_value},
        {"neg_log10_p", ex.neg_log10_p},
        {"calibrated_p", cal.p},
        {"calibrated_neg_log10_p", cal.neg_log10_p},
        {"null_mean", cal.mean},
        {"null_sd", cal.sd},
        {"sign_neg_log10_p", sign_p.neg_log10_p},
        {"matched_statistic", matched.statistic},
        {"matched_neg_log10_p", matched.neg_log10_p},
        {"matched_reading", evidence.readings[static_cast<std::size_t>(st.reading)]},
        {"verdict_p", verdict_p},
        {"verdict_neg_log10_p", mark_p.neg_log10_p},
        {"bit_error_rate", static_cast<double>(wrong_bits) / static_cast<double>(expected.size())},
        {"strength", rec.params.strength},
        {"message",
         {{"text", decoded},
          {"bits", bits_to_string(message)},
          {"tied_bits", ex.tied_bits},
          {"matches_record", matches}}},
        {"verdict", verdict},
        {"p_threshold", kPresentP}};
    if (!reason.empty()) j["reason"] = reason;
    if (a->json) {
      std::cout << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
      return;
    }
    std::ostringstream o;
    // The verdict's p is the larger of the exact and the calibrated one, i.e. the smaller -log10.
    o << "verdict: " << verdict << " (p ";
    if (verdict_p < 1e-300)
      o << "< 1e-300";  // underflows; -log10 p still says how small
    else
      o << "= " << verdict_p;
    o << ", -log10 p = " << mark_p.neg_log10_p << " (signs: exact " << ex.neg_log10_p << ", calibrated "
      << cal.neg_log10_p << "; matched score " << matched.neg_log10_p << "); present needs p < " << kPresentP
      << " and the recorded message)\n";
    if (!reason.empty()) o << "reason: " << reason << "\n";
    o << "message: " << ordered_json(decoded).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace)
      << (matches ? " (as recorded)" : " (differs from the record)") << ", " << wrong_bits << " of "
      << expected.size() << " bits wrong\n";
    o << "correlation: " << ex.correlation << " (" << ex.agreements << " of " << ex.compared << " signs agree)\n";
    o << "resync: " << rs.method;
    if (rs.method == "subdivided" || rs.method == "piece") o << " level " << rs.level;
    if (rs.resubdivided) o << " (level " << rs.level - 1 << " refined once more without crease tags)";
    o << (aligned ? ", similarity fitted" : ", in the original's frame") << ", residual " << rs.residual_rms
      << " of the diagonal\n";
    std::cout << o.str();
  });
}

}  // namespace

void add_mark_commands(CLI::App& app) {
  add_embed_command(app);
  add_extract_command(app);
}

}  // namespace mm::cli
