#include "jobs/evidence_report.h"

#include <sodium.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "geometry/closest_point.h"
#include "quality/surface_distance.h"
#include "registration/align_similarity.h"
#include "render/image.h"
#include "render/render_mesh.h"

namespace mm::jobs {
namespace {

using nlohmann::json;

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

std::string escape(const std::string& s) {
  std::string o;
  o.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      case '\'': o += "&#39;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string text_of(const json& j) {
  if (j.is_string()) return j.get<std::string>();
  if (j.is_null()) return "-";
  return j.dump();
}

std::string base64(const std::vector<std::uint8_t>& bytes) {
  std::string out(sodium_base64_encoded_len(bytes.size(), sodium_base64_VARIANT_ORIGINAL), '\0');
  sodium_bin2base64(out.data(), out.size(), bytes.data(), bytes.size(), sodium_base64_VARIANT_ORIGINAL);
  out.resize(out.size() - 1);  // the terminating NUL
  return out;
}

Points rows_of(const std::vector<Eigen::Vector3d>& v) {
  Points p(static_cast<Eigen::Index>(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i) p.row(static_cast<Eigen::Index>(i)) = v[i].transpose();
  return p;
}

Points strided_rows(const Points& p, int count) {
  if (p.rows() <= count) return p;
  Points o(count, 3);
  for (int i = 0; i < count; ++i) o.row(i) = p.row(static_cast<Eigen::Index>(static_cast<double>(i) * p.rows() / count));
  return o;
}

// Blue (near) through green and yellow to red (far), t in [0, 1].
Rgb heat(double t) {
  t = std::clamp(t, 0.0, 1.0);
  const double r = std::clamp(1.5 - std::abs(4 * t - 3), 0.0, 1.0);
  const double g = std::clamp(1.5 - std::abs(4 * t - 2), 0.0, 1.0);
  const double b = std::clamp(1.5 - std::abs(4 * t - 1), 0.0, 1.0);
  return {static_cast<std::uint8_t>(40 + 215 * r), static_cast<std::uint8_t>(40 + 215 * g),
          static_cast<std::uint8_t>(40 + 215 * b)};
}

// The report's plots: one size, fixed axis ranges.
PlotOptions report_plot(const std::string& title, const std::string& x_label, const std::string& y_label,
                        std::pair<double, double> x, std::pair<double, double> y) {
  PlotOptions o;
  o.width = 800;
  o.height = 420;
  o.title = title;
  o.x_label = x_label;
  o.y_label = y_label;
  o.x_min = x.first;
  o.x_max = x.second;
  o.y_min = y.first;
  o.y_max = y.second;
  return o;
}

void blit(Image& dst, const Image& src, int x0, int y0) {
  for (int y = 0; y < src.height(); ++y)
    for (int x = 0; x < src.width(); ++x) dst.set(x0 + x, y0 + y, src.at(x, y));
}

}  // namespace

std::string odds_in_words(double neg_log10_p) {
  if (!(neg_log10_p > 0)) return "as often as not: no evidence at all";
  if (neg_log10_p < 2) {
    const double times = std::pow(10.0, 2 - neg_log10_p);
    return "about " + fmt("%.0f", times) + " times in 100 trials";
  }
  const int e = static_cast<int>(std::floor(neg_log10_p));
  if (e <= 6) {
    std::string n = "1";
    for (int i = 0; i < e; ++i) n += '0';
    for (int i = static_cast<int>(n.size()) - 3; i > 0; i -= 3) n.insert(static_cast<std::size_t>(i), ",");
    return "less than once in " + n + " trials";
  }
  return "less than once in 10^" + std::to_string(e) + " trials";
}

RegisteredSuspect register_to_original(const Mesh& original, const Mesh& suspect) {
  const TriangleIndex index(original.points, triangle_list(original));
  HintedClosest hinted(index);
  const ClosestPoint closest = [&hinted](const Eigen::Vector3d& q, Eigen::Index row) { return hinted.closest(q, row).point; };
  const Points fixed = rows_of(sample_surface(original, 4000, 1, false));
  const Points moving_samples = rows_of(sample_surface(suspect, 4000, 2, false));
  const IcpResult r = align_similarity(strided_rows(suspect.points, 20000), moving_samples, fixed, closest);
  RegisteredSuspect out{suspect, r.rms};
  out.mesh.points = r.transform.apply(suspect.points);
  return out;
}

ReportPicture side_by_side_picture(const Mesh& original, const Mesh* issued_copy, const Mesh& suspect_registered) {
  constexpr int kW = 420, kH = 360, kLabel = 30;
  Camera cam;
  cam.frame = bounding_sphere(original);
  RenderOptions ro;
  ro.width = kW;
  ro.height = kH;
  Image out(3 * kW, kH + kLabel);
  const std::vector<std::pair<std::string, const Mesh*>> panels = {
      {"ORIGINAL", &original}, {"ISSUED COPY", issued_copy}, {"SUSPECT (REGISTERED)", &suspect_registered}};
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const int x0 = static_cast<int>(i) * kW;
    out.draw_text(x0 + 10, 10, panels[i].first, colours::black, 2);
    if (panels[i].second) {
      blit(out, render_mesh(*panels[i].second, cam, ro), x0, kLabel);
    } else {
      out.draw_text(x0 + 40, kLabel + kH / 2, "FILE NOT AT HAND", colours::grey, 2);
    }
    out.draw_line(x0, 0, x0, kH + kLabel - 1, colours::light_grey);
  }
  return {"side-by-side", "The part, the copy issued and the suspect",
          "Rendered from the same camera. The suspect was brought into the original's position and size by a "
          "similarity transform (scale, rotation, translation) before rendering.",
          out.png()};
}

ReportPicture distance_picture(const Mesh& original, const Mesh& suspect_registered) {
  const TriangleIndex index(original.points, triangle_list(original));
  std::vector<double> d(suspect_registered.faces.size(), 0.0);
  double largest = 0;
  for (std::size_t f = 0; f < suspect_registered.faces.size(); ++f) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int v : suspect_registered.faces[f]) c += suspect_registered.points.row(v).transpose();
    if (suspect_registered.faces[f].empty()) continue;
    c /= static_cast<double>(suspect_registered.faces[f].size());
    d[f] = index.closest(c).distance;
    largest = std::max(largest, d[f]);
  }
  const auto sphere = bounding_sphere(original);
  const double diagonal = 2 * sphere.second;
  RenderOptions ro;
  ro.width = 640;
  ro.height = 480;
  ro.draw_creases = false;
  ro.face_colours.resize(d.size());
  for (std::size_t f = 0; f < d.size(); ++f) ro.face_colours[f] = heat(largest > 0 ? d[f] / largest : 0);
  Camera cam;
  cam.frame = sphere;
  Image img = render_mesh(suspect_registered, cam, ro);
  for (int x = 0; x < 200; ++x)
    for (int y = 0; y < 12; ++y) img.set(420 + x, 455 + y, heat(x / 199.0));
  img.draw_text(380, 457, "0", colours::black);
  img.draw_text(625, 457, "MAX", colours::black);
  const std::string pct = fmt("%.3g", diagonal > 0 ? 100 * largest / diagonal : 0.0);
  return {"distance", "The suspect over the original, coloured by distance",
          "Each face of the registered suspect coloured by its distance to the original surface: blue is on it, "
          "red is the largest distance, " + pct + " % of the part's bounding-box diagonal.",
          img.png()};
}

ReportPicture null_picture(double observed_z, const std::vector<double>& other_z, const std::string& copy_label) {
  PlotSeries density{"null density", {}, colours::blue, false};
  double hi = std::max({4.0, observed_z + 1, other_z.empty() ? 0.0 : *std::max_element(other_z.begin(), other_z.end()) + 1});
  double lo = std::min({-4.0, observed_z - 1, other_z.empty() ? 0.0 : *std::min_element(other_z.begin(), other_z.end()) - 1});
  const int n = 400;
  for (int i = 0; i <= n; ++i) {
    const double z = lo + (hi - lo) * i / n;
    density.points.push_back({z, std::exp(-0.5 * z * z) / std::sqrt(2 * M_PI)});
  }
  PlotSeries observed{copy_label, {{observed_z, 0}, {observed_z, 0.42}}, colours::red, false};
  std::vector<PlotSeries> s = {density, observed};
  // Markers only: each copy its own one-point series, so no line joins them.
  for (std::size_t i = 0; i < other_z.size(); ++i)
    s.push_back({i == 0 ? "other copies" : "", {{other_z[i], 0.01}}, colours::grey, true});
  const PlotOptions o = report_plot("SIGN STATISTIC AGAINST ITS NULL (Z)", "Z = (CORRELATION - NULL MEAN) / NULL SD",
                                    "DENSITY", {lo, hi}, {0, 0.45});
  return {"null", "The observed statistic against chance",
          "The curve is the distribution the sign statistic follows when a mesh carries no mark of the copy "
          "(measured on unrelated key sequences); the red line is this suspect's value for " + copy_label +
              ", grey squares the other copies'. Far to the right of the curve means far beyond chance.",
          plot_lines(s, o).png()};
}

ReportPicture copy_scores_picture(const std::vector<std::pair<std::string, double>>& copies_neg_log10_p,
                                  double threshold_neg_log10_p) {
  std::vector<PlotSeries> s;
  double top = threshold_neg_log10_p + 1;
  for (std::size_t i = 0; i < copies_neg_log10_p.size(); ++i) {
    const double v = copies_neg_log10_p[i].second;
    top = std::max(top, v + 1);
    s.push_back({copies_neg_log10_p[i].first, {{static_cast<double>(i + 1), 0}, {static_cast<double>(i + 1), v}},
                 v > threshold_neg_log10_p ? colours::red : colours::blue, true});
  }
  s.push_back({"THRESHOLD",
               {{0.5, threshold_neg_log10_p}, {static_cast<double>(copies_neg_log10_p.size()) + 0.5, threshold_neg_log10_p}},
               colours::orange, false});
  const PlotOptions o = report_plot("EVERY COPY TRIED: -LOG10 CORRECTED P", "COPY (IN THE ORDER TRIED)", "-LOG10 P",
                                    {0.5, static_cast<double>(copies_neg_log10_p.size()) + 0.5}, {0, top});
  return {"copies", "Every copy of the part, scored",
          "One bar per issued copy of the part. A copy is named only when its bar rises above the threshold "
          "line (red bars).",
          plot_lines(s, o).png()};
}

std::string evidence_html(const json& pr, const std::vector<ReportPicture>& pictures) {
  std::ostringstream h;
  const json& det = pr.at("detection");
  const std::string verdict = det.value("verdict", "");
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
    << "<title>meshmark evidence " << escape(pr.value("case_id", "")) << "</title>\n"
    << "<style>body{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}"
       ".verdict{border:3px solid #333;padding:1em;background:#f6f6f6}.attributed{border-color:#b00}"
       "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:4px 8px;text-align:left;"
       "vertical-align:top}code,pre{font-size:90%;word-break:break-all;white-space:pre-wrap}"
       "img{max-width:100%;border:1px solid #ccc}</style></head><body>\n";
  h << "<h1>Detection evidence: case " << escape(pr.value("case_id", "")) << "</h1>\n";
  h << "<div id=\"verdict\" class=\"verdict " << (verdict == "attributed" ? "attributed" : "") << "\">\n";
  const json& names = pr.at("attributed");
  const std::string suspect = det.value("suspect_name", "");
  const std::string part = pr.contains("asset") && pr["asset"].is_object() ? pr["asset"].value("name", "") : "";
  if (verdict == "attributed" && !names.empty()) {
    h << "<p><b>Verdict: the suspect file <code>" << escape(suspect) << "</code> is a copy of part <code>"
      << escape(part) << "</code> issued to ";
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (i) h << (i + 1 == names.size() ? " and " : ", ");
      h << "customer <span class=\"customer\">" << escape(names[i].value("customer", "")) << "</span> (copy "
        << names[i].value("copy_id", 0) << ", issued " << escape(names[i].value("issued_at", "")) << ")";
    }
    h << ".</b></p>\n";
    for (const auto& a : names)
      h << "<p>How sure, for customer " << escape(a.value("customer", "")) << ": if this file carried no mark of "
        << "that copy, a score this high would occur " << escape(odds_in_words(a.value("neg_log10_corrected_p", 0.0)))
        << " (corrected for the " << det.value("copies_tried", 0) << " copies tried; -log10 p = "
        << fmt("%.1f", a.value("neg_log10_corrected_p", 0.0)) << ").</p>\n";
  } else {
    h << "<p><b>Verdict: " << escape(verdict) << ".</b> The suspect file <code>" << escape(suspect)
      << "</code> is not attributed to any customer.";
    if (!det.value("reason", "").empty()) h << " " << escape(det.value("reason", ""));
    h << "</p>\n";
  }
  const json& method = pr.at("method");
  if (method.contains("false_attribution") && method["false_attribution"].is_object()) {
    const json& fa = method["false_attribution"];
    h << "<p>The method's measured error rate: " << fa.value("false_attributions", 0) << " false attributions in "
      << fa.value("trials", 0) << " innocent trials";
    if (fa.contains("upper_bound_95") && fa["upper_bound_95"].is_number())
      h << " (95 % upper bound on the rate per trial: " << fmt("%.2g", fa["upper_bound_95"].get<double>()) << ")";
    h << ", measured by <code>" << escape(fa.value("command", "")) << "</code> at commit "
      << escape(fa.value("commit", "")) << " on " << escape(fa.value("run", "")) << ".</p>\n";
  }
  h << "<p>How to check: <code>meshmark verify PACKAGE_DIR --pubkey KEY</code> checks the signature and every "
       "hash, with the installation's public key (<code>meshmark evidence pubkey</code>); <code>meshmark reproduce "
    << det.value("id", 0) << "</code> on the installation recomputes the detection from its records and "
       "compares every number.</p>\n</div>\n";

  for (const auto& p : pictures)
    h << "<h2>" << escape(p.title) << "</h2>\n<figure><img id=\"pic-" << escape(p.id) << "\" alt=\""
      << escape(p.title) << "\" src=\"data:image/png;base64," << base64(p.png) << "\"><figcaption>"
      << escape(p.caption) << "</figcaption></figure>\n";

  h << "<h2>Every copy tried</h2>\n<table><tr><th>copy</th><th>customer</th><th>-log10 corrected p</th>"
       "<th>statistics</th><th>payload decoded whole</th></tr>\n";
  for (const auto& c : pr.at("copies")) {
    h << "<tr><td>" << c.value("copy_id", 0) << "</td><td>" << escape(c.value("customer", "")) << "</td><td>"
      << fmt("%.2f", c.value("neg_log10_corrected_p", 0.0)) << "</td><td>";
    for (const auto& [k, v] : c.at("statistics").items()) h << escape(k) << " " << escape(text_of(v)) << "<br>";
    h << "</td><td>" << (c.value("payload_matches", false) ? "yes" : "no") << "</td></tr>\n";
  }
  h << "</table>\n";

  h << "<h2>The method</h2>\n<p>" << escape(method.value("statistic", "")) << "</p>\n<p>"
    << escape(method.value("decision_rule", "")) << "</p>\n";

  h << "<h2>Chain of records</h2>\n<table><tr><th>time (UTC)</th><th>actor</th><th>action</th><th>subject</th>"
       "<th>details</th></tr>\n";
  for (const auto& e : pr.at("chain"))
    h << "<tr><td>" << escape(e.value("at", "")) << "</td><td>" << escape(e.value("actor", "")) << "</td><td>"
      << escape(e.value("action", "")) << "</td><td>" << escape(e.value("subject", "")) << "</td><td><code>"
      << escape(text_of(e.value("details", json::object()))) << "</code></td></tr>\n";
  h << "</table>\n";

  h << "<h2>Files and their SHA-256</h2>\n<table><tr><th>role</th><th>name</th><th>SHA-256</th></tr>\n";
  for (const auto& f : pr.at("files"))
    h << "<tr><td>" << escape(f.value("role", "")) << "</td><td>" << escape(f.value("name", "")) << "</td><td><code>"
      << escape(f.value("sha256", "")) << "</code></td></tr>\n";
  h << "</table>\n";

  h << "<h2>Versions, parameters and records</h2>\n<pre>"
    << escape(json{{"meshmark", pr.at("meshmark")}, {"configuration", pr.at("configuration")},
                   {"timestamp", pr.at("timestamp")}, {"records", pr.at("records")}}
                  .dump(2))
    << "</pre>\n"
    // For checkers: once loaded, the body says how many pictures the browser decoded.
    << "<script>window.addEventListener('load',function(){var n=0;for(var i of document.images)"
       "if(i.complete&&i.naturalWidth>0)n++;document.body.setAttribute('data-pictures-decoded',n);});</script>\n"
    << "</body></html>\n";
  return h.str();
}

}  // namespace mm::jobs
