// A small RGB raster for pictures and plots: pixels, lines, depth-tested triangles, a built-in
// 5x7 bitmap font, PNG output. No anti-aliasing: pictures are for inspection, and exact pixels
// keep the renderer deterministic and testable.
#pragma once
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace mm {

struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Rgb& o) const { return r == o.r && g == o.g && b == o.b; }
  bool operator!=(const Rgb& o) const { return !(*this == o); }
};

namespace colours {
constexpr Rgb white{255, 255, 255};
constexpr Rgb black{0, 0, 0};
constexpr Rgb grey{128, 128, 128};
constexpr Rgb light_grey{220, 220, 220};
constexpr Rgb red{220, 30, 30};
constexpr Rgb green{30, 160, 60};
constexpr Rgb blue{40, 80, 220};
constexpr Rgb orange{240, 140, 20};
constexpr Rgb purple{140, 60, 180};
}  // namespace colours

// Screen-space point for depth-tested drawing: x right, y down (pixels), smaller z is nearer.
struct ScreenPoint {
  double x = 0, y = 0, z = 0;
};

class Image {
 public:
  // Throws std::invalid_argument for non-positive or absurd sizes (> 16384 per side).
  Image(int width, int height, Rgb background = colours::white);

  int width() const { return width_; }
  int height() const { return height_; }

  void fill(Rgb colour);
  // Pixels outside the image are ignored, so callers can draw partly off-screen shapes.
  void set(int x, int y, Rgb colour);
  Rgb at(int x, int y) const;  // throws std::out_of_range outside

  // Bresenham line (no depth test); thickness grows the pen into a square.
  void draw_line(int x0, int y0, int x1, int y1, Rgb colour, int thickness = 1);

  // Depth buffer, initially +infinity everywhere; cleared by fill() and clear_depth().
  void clear_depth();
  float depth(int x, int y) const;  // throws std::out_of_range outside
  // Filled triangle with z-buffer: pixel centres inside the triangle (top-left rule) whose
  // interpolated depth is nearer than the buffer are written.
  void fill_triangle(const ScreenPoint& a, const ScreenPoint& b, const ScreenPoint& c, Rgb colour);
  // Line with depth test; depth_bias is subtracted so edges lying on a surface stay visible.
  void draw_line_depth(const ScreenPoint& a, const ScreenPoint& b, Rgb colour, double depth_bias,
                       int thickness = 1);

  // Text in the built-in 5x7 font (digits, A-Z, lower case drawn as upper case, space and
  // . - : % ( ) / = + , _ ' ? <>; anything else draws as '?'). (x, y) is the top-left corner;
  // each glyph takes 6x8 cells times scale.
  void draw_text(int x, int y, const std::string& text, Rgb colour, int scale = 1);
  static int text_width(const std::string& text, int scale = 1);
  static int text_height(int scale = 1) { return 7 * scale; }

  // Writes a PNG (8-bit RGB) to a temporary file beside path and renames it into place.
  // Throws std::runtime_error naming the path on failure, leaving no partial file.
  void write_png(const std::string& path) const;
  // The same PNG in memory (for pages that embed their pictures).
  std::vector<std::uint8_t> png() const;

  const std::vector<std::uint8_t>& rgb() const { return pixels_; }

 private:
  int width_, height_;
  std::vector<std::uint8_t> pixels_;  // row-major RGB
  std::vector<float> depth_;
};

// One curve in a line plot.
struct PlotSeries {
  std::string label;                               // legend text; empty = not in the legend
  std::vector<std::pair<double, double>> points;   // (x, y) in data units, drawn in order
  Rgb colour = colours::blue;
  bool markers = true;                             // small squares at the data points
};

struct PlotOptions {
  int width = 800, height = 500;
  std::string title, x_label, y_label;
  // Axis ranges; when min >= max the range is taken from the data (with a little margin).
  double x_min = 0, x_max = 0, y_min = 0, y_max = 0;
  int x_ticks = 5, y_ticks = 5;                    // approximate number of tick intervals
};

// Line plot with axes, "nice" tick values and labels, a legend and a title.
// Non-finite points are skipped. Throws std::invalid_argument for impossible sizes.
Image plot_lines(const std::vector<PlotSeries>& series, const PlotOptions& options);

}  // namespace mm
