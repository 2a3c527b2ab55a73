#include "render/image.h"

#include <png.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <system_error>

#include "support/atomic_file.h"

namespace mm {
namespace {

constexpr int kMaxSide = 16384;

// 5x7 glyphs, one byte per row, bit 4 = leftmost column.
struct Glyph {
  char c;
  std::array<std::uint8_t, 7> rows;
};

constexpr Glyph kFont[] = {
    {' ', {0, 0, 0, 0, 0, 0, 0}},
    {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}},
    {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}},
    {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E}},
    {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}},
    {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}},
    {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}},
    {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
    {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}},
    {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}},
    {'A', {0x0E, 0x11, 0x11, 0x11, 0x1F, 0x11, 0x11}},
    {'B', {0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E}},
    {'C', {0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E}},
    {'D', {0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C}},
    {'E', {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F}},
    {'F', {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10}},
    {'G', {0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F}},
    {'H', {0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11}},
    {'I', {0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'J', {0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C}},
    {'K', {0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11}},
    {'L', {0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F}},
    {'M', {0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11}},
    {'N', {0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11}},
    {'O', {0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}},
    {'P', {0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10}},
    {'Q', {0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D}},
    {'R', {0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11}},
    {'S', {0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E}},
    {'T', {0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04}},
    {'U', {0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}},
    {'V', {0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04}},
    {'W', {0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A}},
    {'X', {0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11}},
    {'Y', {0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04}},
    {'Z', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C}},
    {'-', {0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00}},
    {':', {0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00}},
    {'%', {0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03}},
    {'(', {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02}},
    {')', {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08}},
    {'/', {0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00}},
    {'=', {0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00}},
    {'+', {0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00}},
    {',', {0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08}},
    {'_', {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F}},
    {'\'', {0x0C, 0x04, 0x08, 0x00, 0x00, 0x00, 0x00}},
    {'<', {0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02}},
    {'>', {0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08}},
    {'?', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04}},
};

const std::array<std::uint8_t, 7>& glyph_rows(char c) {
  if (c >= 'a' && c <= 'z') c = static_cast<char>(c - 'a' + 'A');
  for (const Glyph& g : kFont)
    if (g.c == c) return g.rows;
  for (const Glyph& g : kFont)
    if (g.c == '?') return g.rows;
  return kFont[0].rows;
}

// Calls plot(x, y) for every pixel of the Bresenham line.
template <class Plot>
void bresenham(int x0, int y0, int x1, int y1, Plot plot) {
  const long dx = std::labs(static_cast<long>(x1) - x0), dy = -std::labs(static_cast<long>(y1) - y0);
  const int sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
  long err = dx + dy;
  for (;;) {
    plot(x0, y0);
    if (x0 == x1 && y0 == y1) break;
    const long e2 = 2 * err;
    if (e2 >= dy) { err += dy; x0 += sx; }
    if (e2 <= dx) { err += dx; y0 += sy; }
  }
}

// Clamps a screen coordinate into int range so hostile or far-away geometry cannot overflow.
int clamp_coord(double v) {
  if (!std::isfinite(v)) return v > 0 ? 1 << 20 : -(1 << 20);
  return static_cast<int>(std::lround(std::clamp(v, -1e6, 1e6)));
}

}  // namespace

Image::Image(int width, int height, Rgb background) : width_(width), height_(height) {
  if (width <= 0 || height <= 0 || width > kMaxSide || height > kMaxSide)
    throw std::invalid_argument("image size " + std::to_string(width) + "x" +
                                std::to_string(height) + " out of range");
  pixels_.resize(static_cast<size_t>(width) * height * 3);
  depth_.resize(static_cast<size_t>(width) * height);
  fill(background);
}

void Image::fill(Rgb colour) {
  for (size_t i = 0; i < pixels_.size(); i += 3) {
    pixels_[i] = colour.r;
    pixels_[i + 1] = colour.g;
    pixels_[i + 2] = colour.b;
  }
  clear_depth();
}

void Image::clear_depth() {
  std::fill(depth_.begin(), depth_.end(), std::numeric_limits<float>::infinity());
}

void Image::set(int x, int y, Rgb colour) {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return;
  const size_t i = (static_cast<size_t>(y) * width_ + x) * 3;
  pixels_[i] = colour.r;
  pixels_[i + 1] = colour.g;
  pixels_[i + 2] = colour.b;
}

Rgb Image::at(int x, int y) const {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) throw std::out_of_range("pixel outside image");
  const size_t i = (static_cast<size_t>(y) * width_ + x) * 3;
  return {pixels_[i], pixels_[i + 1], pixels_[i + 2]};
}

float Image::depth(int x, int y) const {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) throw std::out_of_range("pixel outside image");
  return depth_[static_cast<size_t>(y) * width_ + x];
}

void Image::draw_line(int x0, int y0, int x1, int y1, Rgb colour, int thickness) {
  const int lo = -(std::max(thickness, 1) - 1) / 2, hi = lo + std::max(thickness, 1);
  // Skip lines entirely off-screen (also bounds the Bresenham loop for far-away endpoints).
  if (std::max(x0, x1) + hi < 0 || std::min(x0, x1) + lo >= width_ ||
      std::max(y0, y1) + hi < 0 || std::min(y0, y1) + lo >= height_)
    return;
  bresenham(x0, y0, x1, y1, [&](int x, int y) {
    for (int oy = lo; oy < hi; ++oy)
      for (int ox = lo; ox < hi; ++ox) set(x + ox, y + oy, colour);
  });
}

void Image::fill_triangle(const ScreenPoint& a, const ScreenPoint& b, const ScreenPoint& c,
                          Rgb colour) {
  const double area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
  if (!(std::abs(area) > 1e-12)) return;  // degenerate or NaN
  const int x_lo = std::max(0, static_cast<int>(std::floor(std::min({a.x, b.x, c.x}))));
  const int x_hi = std::min(width_ - 1, static_cast<int>(std::ceil(std::max({a.x, b.x, c.x}))));
  const int y_lo = std::max(0, static_cast<int>(std::floor(std::min({a.y, b.y, c.y}))));
  const int y_hi = std::min(height_ - 1, static_cast<int>(std::ceil(std::max({a.y, b.y, c.y}))));
  for (int y = y_lo; y <= y_hi; ++y) {
    const double py = y + 0.5;
    for (int x = x_lo; x <= x_hi; ++x) {
      const double px = x + 0.5;
      // Barycentric weights from edge functions, normalised by the signed area so both
      // windings fill.
      const double w0 = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) / area;
      const double w1 = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) / area;
      const double w2 = 1.0 - w0 - w1;
      if (w0 < 0 || w1 < 0 || w2 < 0) continue;
      const float z = static_cast<float>(w0 * a.z + w1 * b.z + w2 * c.z);
      float& d = depth_[static_cast<size_t>(y) * width_ + x];
      if (z < d) {
        d = z;
        set(x, y, colour);
      }
    }
  }
}

void Image::draw_line_depth(const ScreenPoint& a, const ScreenPoint& b, Rgb colour,
                            double depth_bias, int thickness) {
  const int x0 = clamp_coord(a.x), y0 = clamp_coord(a.y);
  const int x1 = clamp_coord(b.x), y1 = clamp_coord(b.y);
  const int lo = -(std::max(thickness, 1) - 1) / 2, hi = lo + std::max(thickness, 1);
  if (std::max(x0, x1) + hi < 0 || std::min(x0, x1) + lo >= width_ ||
      std::max(y0, y1) + hi < 0 || std::min(y0, y1) + lo >= height_)
    return;
  const double len2 = double(x1 - x0) * (x1 - x0) + double(y1 - y0) * (y1 - y0);
  bresenham(x0, y0, x1, y1, [&](int x, int y) {
    // Depth interpolated along the line by the pixel's projection onto it.
    const double t = len2 > 0 ? std::clamp(((x - x0) * double(x1 - x0) + (y - y0) * double(y1 - y0)) / len2, 0.0, 1.0) : 0.0;
    const float z = static_cast<float>(a.z + t * (b.z - a.z) - depth_bias);
    for (int oy = lo; oy < hi; ++oy)
      for (int ox = lo; ox < hi; ++ox) {
        const int px = x + ox, py = y + oy;
        if (px < 0 || py < 0 || px >= width_ || py >= height_) continue;
        float& d = depth_[static_cast<size_t>(py) * width_ + px];
        if (z <= d) {
          d = z;
          set(px, py, colour);
        }
      }
  });
}

void Image::draw_text(int x, int y, const std::string& text, Rgb colour, int scale) {
  scale = std::max(scale, 1);
  int cx = x;
  for (char c : text) {
    const auto& rows = glyph_rows(c);
    for (int r = 0; r < 7; ++r)
      for (int col = 0; col < 5; ++col)
        if (rows[r] & (0x10 >> col))
          for (int sy = 0; sy < scale; ++sy)
            for (int sx = 0; sx < scale; ++sx) set(cx + col * scale + sx, y + r * scale + sy, colour);
    cx += 6 * scale;
  }
}

int Image::text_width(const std::string& text, int scale) {
  if (text.empty()) return 0;
  return static_cast<int>(text.size()) * 6 * std::max(scale, 1) - std::max(scale, 1);
}

std::vector<std::uint8_t> Image::png() const {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width_);
  image.height = static_cast<png_uint_32>(height_);
  image.format = PNG_FORMAT_RGB;
  png_alloc_size_t size = 0;
  if (!png_image_write_to_memory(&image, nullptr, &size, 0, pixels_.data(), 0, nullptr))
    throw std::runtime_error(std::string("PNG encoding failed: ") + image.message);
  std::vector<std::uint8_t> buffer(size);
  if (!png_image_write_to_memory(&image, buffer.data(), &size, 0, pixels_.data(), 0, nullptr))
    throw std::runtime_error(std::string("PNG encoding failed: ") + image.message);
  png_image_free(&image);
  buffer.resize(size);
  return buffer;
}

void Image::write_png(const std::string& path) const {
  std::vector<std::uint8_t> buffer;
  try {
    buffer = png();
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
  try {
    support::write_file_atomic(path, buffer);
  } catch (const std::system_error& e) {
    throw std::runtime_error(path + ": writing the PNG failed: " + e.what());
  }
}

// ---------------------------------------------------------------------------------------------
// Line plot

namespace {

struct Range {
  double lo, hi;
};

// Step of 1, 2 or 5 times a power of ten giving about `n` intervals over the range.
double nice_step(double span, int n) {
  const double raw = span / std::max(n, 1);
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  const double m = raw / p;
  return (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10) * p;
}

std::string tick_label(double v, double step) {
  if (std::abs(v) < step * 1e-6) v = 0;  // avoid "-0" and 1e-17 noise
  char buf[64];
  const double mag = std::max(std::abs(v), step);
  if (mag >= 1e6 || step < 1e-4) {
    std::snprintf(buf, sizeof buf, "%.3g", v);
  } else {
    const int decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  }
  return buf;
}

Range data_range(const std::vector<PlotSeries>& series, bool x_axis, double lo, double hi) {
  if (lo < hi) return {lo, hi};
  double mn = std::numeric_limits<double>::infinity(), mx = -mn;
  for (const auto& s : series)
    for (const auto& [x, y] : s.points) {
      if (!std::isfinite(x) || !std::isfinite(y)) continue;
      const double v = x_axis ? x : y;
      mn = std::min(mn, v);
      mx = std::max(mx, v);
    }
  if (!std::isfinite(mn)) return {0, 1};
  if (mx - mn <= std::abs(mx) * 1e-12) {
    const double pad = mx == 0 ? 1 : std::abs(mx) * 0.1;
    return {mn - pad, mx + pad};
  }
  const double pad = x_axis ? 0 : 0.05 * (mx - mn);
  return {mn - pad, mx + pad};
}

}  // namespace

Image plot_lines(const std::vector<PlotSeries>& series, const PlotOptions& o) {
  Image img(o.width, o.height, colours::white);
  const int left = 70, right = 20, top = o.title.empty() ? 20 : 40, bottom = 55;
  const int pw = o.width - left - right, ph = o.height - top - bottom;
  if (pw < 20 || ph < 20) throw std::invalid_argument("plot too small for axes and labels");

  const Range xr = data_range(series, true, o.x_min, o.x_max);
  const Range yr = data_range(series, false, o.y_min, o.y_max);
  auto sx = [&](double x) { return left + (x - xr.lo) / (xr.hi - xr.lo) * pw; };
  auto sy = [&](double y) { return top + ph - (y - yr.lo) / (yr.hi - yr.lo) * ph; };

  // Grid and ticks.
  const double xs = nice_step(xr.hi - xr.lo, o.x_ticks), ys = nice_step(yr.hi - yr.lo, o.y_ticks);
  for (double v = std::ceil(xr.lo / xs - 1e-9) * xs; v <= xr.hi + xs * 1e-9; v += xs) {
    const int px = clamp_coord(sx(v));
    img.draw_line(px, top, px, top + ph, colours::light_grey);
    img.draw_line(px, top + ph, px, top + ph + 4, colours::black);
    const std::string t = tick_label(v, xs);
    img.draw_text(px - Image::text_width(t) / 2, top + ph + 8, t, colours::black);
  }
  for (double v = std::ceil(yr.lo / ys - 1e-9) * ys; v <= yr.hi + ys * 1e-9; v += ys) {
    const int py = clamp_coord(sy(v));
    img.draw_line(left, py, left + pw, py, colours::light_grey);
    img.draw_line(left - 4, py, left, py, colours::black);
    const std::string t = tick_label(v, ys);
    img.draw_text(left - 8 - Image::text_width(t), py - 3, t, colours::black);
  }
  img.draw_line(left, top, left, top + ph, colours::black);
  img.draw_line(left, top + ph, left + pw, top + ph, colours::black);

  // Curves, clipped to the plot rectangle.
  auto clip_set = [&](int x, int y, Rgb c) {
    if (x >= left && x <= left + pw && y >= top && y <= top + ph) img.set(x, y, c);
  };
  for (const auto& s : series) {
    bool have_prev = false;
    int qx = 0, qy = 0;
    for (const auto& [x, y] : s.points) {
      if (!std::isfinite(x) || !std::isfinite(y)) {
        have_prev = false;
        continue;
      }
      const int px = clamp_coord(sx(x)), py = clamp_coord(sy(y));
      if (have_prev) {
        // Thickness 2 so curves stand out from the grid.
        bresenham(qx, qy, px, py, [&](int lx, int ly) {
          clip_set(lx, ly, s.colour);
          clip_set(lx + 1, ly, s.colour);
          clip_set(lx, ly + 1, s.colour);
        });
      }
      if (s.markers)
        for (int dy = -2; dy <= 2; ++dy)
          for (int dx = -2; dx <= 2; ++dx) clip_set(px + dx, py + dy, s.colour);
      qx = px;
      qy = py;
      have_prev = true;
    }
  }

  // Labels, title, legend.
  if (!o.title.empty())
    img.draw_text((o.width - Image::text_width(o.title, 2)) / 2, 10, o.title, colours::black, 2);
  if (!o.x_label.empty())
    img.draw_text(left + (pw - Image::text_width(o.x_label)) / 2, o.height - 20, o.x_label,
                  colours::black);
  if (!o.y_label.empty()) img.draw_text(4, top - 14 < 0 ? 0 : top - 14, o.y_label, colours::black);

  int legend_w = 0, legend_n = 0;
  for (const auto& s : series)
    if (!s.label.empty()) {
      legend_w = std::max(legend_w, Image::text_width(s.label));
      ++legend_n;
    }
  if (legend_n > 0) {
    const int box_w = legend_w + 36, box_h = legend_n * 14 + 8;
    const int bx = left + pw - box_w - 8, by = top + 8;
    for (int y = by; y < by + box_h; ++y)
      for (int x = bx; x < bx + box_w; ++x) img.set(x, y, colours::white);
    img.draw_line(bx, by, bx + box_w, by, colours::black);
    img.draw_line(bx, by + box_h, bx + box_w, by + box_h, colours::black);
    img.draw_line(bx, by, bx, by + box_h, colours::black);
    img.draw_line(bx + box_w, by, bx + box_w, by + box_h, colours::black);
    int row = 0;
    for (const auto& s : series) {
      if (s.label.empty()) continue;
      const int ly = by + 8 + row * 14;
      img.draw_line(bx + 6, ly + 3, bx + 24, ly + 3, s.colour, 2);
      img.draw_text(bx + 30, ly, s.label, colours::black);
      ++row;
    }
  }
  return img;
}

}  // namespace mm
