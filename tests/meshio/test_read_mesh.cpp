#include "common/shared_meshes.h"
#include "meshio/read_mesh.h"

TEST(ReadMesh, FandiskQuads) {
  MM_REQUIRE_SHARED_MESHES();
  auto m = mm::read_mesh(mm::test::shared_mesh("fandisk_quads.off"));
  EXPECT_EQ(m.num_vertices(), 766);
}
