#include <gtest/gtest.h>

#include <set>
#include <tuple>

#include "render/render_mesh.h"

namespace {

// Unit cube as 6 quads with its 12 edges tagged as creases.
mm::Mesh cube() {
  mm::Mesh m;
  m.points.resize(8, 3);
  for (int i = 0; i < 8; ++i) m.points.row(i) << (i & 1), (i >> 1) & 1, (i >> 2) & 1;
  m.faces = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  m.creases = mm::unique_edges(m);
  return m;
}

int count_if_pixels(const mm::Image& img, bool (*pred)(mm::Rgb)) {
  int n = 0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) n += pred(img.at(x, y));
  return n;
}

}  // namespace

TEST(RenderMesh, CubeIsShadedInTheMiddleAndBackgroundAtCorners) {
  mm::RenderOptions o;
  o.width = 200;
  o.height = 200;
  o.draw_creases = false;
  const mm::Image img = mm::render_mesh(cube(), {}, o);
  EXPECT_NE(img.at(100, 100), o.background);
  EXPECT_EQ(img.at(0, 0), o.background);
  EXPECT_EQ(img.at(199, 199), o.background);
  // Three faces are visible from the default view, with three different shades.
  std::set<std::tuple<int, int, int>> shades;
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 200; ++x) {
      const mm::Rgb c = img.at(x, y);
      if (c != o.background) shades.insert({c.r, c.g, c.b});
    }
  EXPECT_EQ(shades.size(), 3u);
}

TEST(RenderMesh, CreasesAreRedOnlyWhenRequested) {
  mm::RenderOptions o;
  o.width = 200;
  o.height = 200;
  auto red = [](mm::Rgb c) { return c == mm::colours::red; };
  const mm::Image with = mm::render_mesh(cube(), {}, o);
  o.draw_creases = false;
  const mm::Image without = mm::render_mesh(cube(), {}, o);
  EXPECT_GT(count_if_pixels(with, red), 400);  // 9 visible edges, 2 px wide
  EXPECT_EQ(count_if_pixels(without, red), 0);
  // Hidden back edges stay hidden: the crease from (0,0,0) is behind the cube in this view only
  // partly, so compare to drawing all edges without depth: fewer red pixels with the z-buffer.
  mm::Mesh flat = cube();
  flat.faces.clear();  // nothing occludes
  o.draw_creases = true;
  const mm::Image all = mm::render_mesh(flat, {}, o);
  EXPECT_GT(count_if_pixels(all, red), count_if_pixels(with, red));
}

TEST(RenderMesh, WireframeDrawsEdges) {
  mm::RenderOptions o;
  o.width = 200;
  o.height = 200;
  o.draw_creases = false;
  o.draw_wire = true;
  const mm::Image img = mm::render_mesh(cube(), {}, o);
  auto wire = [](mm::Rgb c) { return c == mm::Rgb{60, 60, 60}; };
  EXPECT_GT(count_if_pixels(img, wire), 300);
}

TEST(RenderMesh, SharedFramingKeepsScale) {
  mm::Mesh small = cube();
  small.points *= 0.5;
  mm::Camera cam;
  cam.frame = mm::bounding_sphere(cube());
  mm::RenderOptions o;
  o.width = 200;
  o.height = 200;
  o.draw_creases = false;
  auto fg = [](mm::Rgb c) { return c != mm::colours::white; };
  const int big_px = count_if_pixels(mm::render_mesh(cube(), cam, o), fg);
  const int small_px = count_if_pixels(mm::render_mesh(small, cam, o), fg);
  EXPECT_NEAR(static_cast<double>(small_px) / big_px, 0.25, 0.03);
}

TEST(RenderMesh, RejectsBadIndices) {
  mm::Mesh m = cube();
  m.faces[0][1] = 8;
  EXPECT_THROW(mm::render_mesh(m), mm::InputError);
  m = cube();
  m.creases.push_back({0, 99});
  EXPECT_THROW(mm::render_mesh(m), mm::InputError);
  m = cube();
  m.faces.push_back({0, 1});
  EXPECT_THROW(mm::render_mesh(m), mm::InputError);
  EXPECT_NO_THROW(mm::render_mesh(mm::Mesh{}));
}
