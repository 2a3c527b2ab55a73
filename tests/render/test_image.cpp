#include <gtest/gtest.h>
#include <png.h>

#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "render/image.h"

namespace {

int count_colour(const mm::Image& img, mm::Rgb c) {
  int n = 0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) n += img.at(x, y) == c;
  return n;
}

std::filesystem::path temp_dir() {
  auto d = std::filesystem::temp_directory_path() / ("mm_render_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(d);
  return d;
}

}  // namespace

TEST(Image, RejectsBadSizes) {
  EXPECT_THROW(mm::Image(0, 10), std::invalid_argument);
  EXPECT_THROW(mm::Image(10, -1), std::invalid_argument);
  EXPECT_THROW(mm::Image(100000, 10), std::invalid_argument);
}

TEST(Image, SetAndFillIgnoreOutside) {
  mm::Image img(4, 3, mm::colours::white);
  img.set(1, 2, mm::colours::red);
  img.set(-1, 0, mm::colours::red);
  img.set(4, 0, mm::colours::red);
  EXPECT_EQ(img.at(1, 2), mm::colours::red);
  EXPECT_EQ(count_colour(img, mm::colours::red), 1);
  EXPECT_THROW(img.at(4, 0), std::out_of_range);
  img.fill(mm::colours::black);
  EXPECT_EQ(count_colour(img, mm::colours::black), 12);
}

TEST(Image, LinesCoverEndpointsAndStayConnected) {
  mm::Image img(50, 50);
  img.draw_line(3, 4, 40, 20, mm::colours::blue);
  EXPECT_EQ(img.at(3, 4), mm::colours::blue);
  EXPECT_EQ(img.at(40, 20), mm::colours::blue);
  // An x-major Bresenham line sets exactly one pixel per column.
  EXPECT_EQ(count_colour(img, mm::colours::blue), 38);
  mm::Image img2(50, 50);
  img2.draw_line(10, 10, 10, 30, mm::colours::blue, 3);
  // A 3x3 square pen: 3 columns, and the pen overhangs each end by one row.
  EXPECT_EQ(count_colour(img2, mm::colours::blue), 23 * 3);
  // Far-away endpoints are clipped without looping over millions of pixels.
  img2.draw_line(-1000000, 25, 1000000, 25, mm::colours::red);
  EXPECT_EQ(img2.at(0, 25), mm::colours::red);
  EXPECT_EQ(img2.at(49, 25), mm::colours::red);
}

TEST(Image, TriangleFillsHalfSquareAndRespectsDepth) {
  mm::Image img(100, 100);
  // Two triangles covering the square [10,90)^2: every pixel centre inside is covered.
  img.fill_triangle({10, 10, 5}, {90, 10, 5}, {90, 90, 5}, mm::colours::red);
  img.fill_triangle({10, 10, 5}, {90, 90, 5}, {10, 90, 5}, mm::colours::red);
  EXPECT_EQ(count_colour(img, mm::colours::red), 80 * 80);
  // A farther triangle does not overwrite, a nearer one does.
  img.fill_triangle({0, 0, 9}, {100, 0, 9}, {0, 100, 9}, mm::colours::green);
  EXPECT_EQ(img.at(20, 20), mm::colours::red);
  EXPECT_EQ(img.at(2, 2), mm::colours::green);
  img.fill_triangle({0, 0, 1}, {100, 0, 1}, {0, 100, 1}, mm::colours::blue);
  EXPECT_EQ(img.at(20, 20), mm::colours::blue);
  EXPECT_FLOAT_EQ(img.depth(20, 20), 1.0f);
  // Clockwise winding fills too; degenerate triangles fill nothing.
  mm::Image img2(20, 20);
  img2.fill_triangle({0, 0, 0}, {0, 20, 0}, {20, 0, 0}, mm::colours::red);
  EXPECT_GT(count_colour(img2, mm::colours::red), 150);
  mm::Image img3(20, 20);
  img3.fill_triangle({0, 0, 0}, {10, 10, 0}, {20, 20, 0}, mm::colours::red);
  EXPECT_EQ(count_colour(img3, mm::colours::red), 0);
}

TEST(Image, TextDrawsKnownGlyphs) {
  mm::Image img(60, 10);
  img.draw_text(0, 0, "1", mm::colours::black);
  // Glyph '1': rows 04 0C 04 04 04 04 0E -> 1+2+1+1+1+1+3 = 10 pixels.
  EXPECT_EQ(count_colour(img, mm::colours::black), 10);
  EXPECT_EQ(img.at(2, 0), mm::colours::black);
  EXPECT_EQ(img.at(1, 6), mm::colours::black);
  mm::Image big(60, 20);
  big.draw_text(0, 0, "1", mm::colours::black, 2);
  EXPECT_EQ(count_colour(big, mm::colours::black), 40);
  EXPECT_EQ(mm::Image::text_width("abc"), 17);
  // Lower case draws as upper case.
  mm::Image lo(20, 10), up(20, 10);
  lo.draw_text(0, 0, "q", mm::colours::black);
  up.draw_text(0, 0, "Q", mm::colours::black);
  EXPECT_EQ(lo.rgb(), up.rgb());
}

TEST(Image, PngRoundTrip) {
  mm::Image img(31, 17, mm::colours::white);
  img.draw_line(0, 0, 30, 16, mm::colours::red);
  img.draw_text(2, 8, "A-1:", mm::Rgb{1, 2, 3});
  const auto path = (temp_dir() / "round.png").string();
  img.write_png(path);
  png_image in{};
  in.version = PNG_IMAGE_VERSION;
  ASSERT_TRUE(png_image_begin_read_from_file(&in, path.c_str()));
  in.format = PNG_FORMAT_RGB;
  ASSERT_EQ(in.width, 31u);
  ASSERT_EQ(in.height, 17u);
  std::vector<std::uint8_t> buf(PNG_IMAGE_SIZE(in));
  ASSERT_TRUE(png_image_finish_read(&in, nullptr, buf.data(), 0, nullptr));
  EXPECT_EQ(buf, img.rgb());
  // No temporary files left behind.
  int files = 0;
  for (auto& e : std::filesystem::directory_iterator(temp_dir())) files += e.is_regular_file();
  EXPECT_EQ(files, 1);
  std::filesystem::remove_all(temp_dir());
}

TEST(Image, PngWriteToMissingFolderThrows) {
  mm::Image img(4, 4);
  EXPECT_THROW(img.write_png("/nonexistent-folder-mm/x.png"), std::runtime_error);
}

TEST(Plot, SeriesAxesAndLegendAppear) {
  mm::PlotSeries a{"method 1", {{0, 0}, {0.001, 0.5}, {0.002, 1.0}}, mm::colours::red};
  mm::PlotSeries b{"method 2", {{0, 1.0}, {0.002, 0.0}}, mm::colours::blue, false};
  mm::PlotOptions o;
  o.title = "Correlation";
  o.x_label = "noise";
  o.y_label = "corr";
  const mm::Image img = mm::plot_lines({a, b}, o);
  EXPECT_EQ(img.width(), 800);
  EXPECT_GT(count_colour(img, mm::colours::red), 200);
  EXPECT_GT(count_colour(img, mm::colours::blue), 200);
  EXPECT_GT(count_colour(img, mm::colours::black), 500);  // axes, ticks, labels, title
  // The x axis is a solid black line along the bottom of the plot area (height - 55).
  for (int x = 80; x < 770; x += 37) EXPECT_EQ(img.at(x, o.height - 55), mm::colours::black);
  // A series point outside a fixed range is clipped, not drawn over the margins.
  mm::PlotOptions fixed = o;
  fixed.y_min = 0;
  fixed.y_max = 0.5;
  const mm::Image clipped = mm::plot_lines({mm::PlotSeries{"", {{0, 0}, {1, 100}}, mm::colours::green}}, fixed);
  for (int x = 0; x < clipped.width(); ++x)
    for (int y = 0; y < 40; ++y) EXPECT_NE(clipped.at(x, y), mm::colours::green);
  mm::PlotOptions tiny;
  tiny.width = tiny.height = 50;
  EXPECT_THROW(mm::plot_lines({a}, tiny), std::invalid_argument);
}
