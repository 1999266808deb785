// Figures in .vdb load refusals: voxel sizes far from 1 print in full, not as fixed six-decimal numbers.
#include <string>

#include <gtest/gtest.h>
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include "support/test_paths.h"
#include "voxel/error.h"
#include "voxel/voxel_object.h"

namespace {

namespace fs = std::filesystem;

std::string loadRefusal(const fs::path& file) {
  try {
    vs::LoadOptions options;
    options.checkInChildProcess = false;  // written here
    vs::loadVdb(file.string(), options);
  } catch (const vs::Error& e) {
    EXPECT_EQ(e.kind(), vs::ErrorKind::BadInput);
    return e.what();
  }
  ADD_FAILURE() << file << ": accepted";
  return "";
}

TEST(VdbMessages, VoxelSizesOutsideTheRangeAreGivenInFull) {
  openvdb::initialize();
  const fs::path dir = vs::test::scratchDir("vdb_messages");
  struct Case {
    double size;
    const char* text;
  } cases[] = {{5e-5, "has a voxel size of 5e-05 along axis 0; the valid range is 0.0001 to 10000"},
               {2.5e7, "has a voxel size of 2.5e+07 along axis 0; the valid range is 0.0001 to 10000"}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.text);
    auto grid = openvdb::BoolGrid::create(false);
    grid->setName("mask");
    grid->tree().setValueOn({0, 0, 0}, true);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(c.size));
    const fs::path file = dir / "g.vdb";
    openvdb::io::File(file.string()).write({grid});
    std::string e = loadRefusal(file);
    EXPECT_NE(e.find(c.text), std::string::npos) << e;
    EXPECT_EQ(e.find("0.0000"), std::string::npos) << e;
  }
}

TEST(VdbMessages, TranslationsOutsideTheRangeAreGivenInFull) {
  openvdb::initialize();
  const fs::path dir = vs::test::scratchDir("vdb_messages_translation");
  auto grid = openvdb::BoolGrid::create(false);
  grid->setName("mask");
  grid->tree().setValueOn({0, 0, 0}, true);
  openvdb::math::Transform::Ptr t = openvdb::math::Transform::createLinearTransform(1.0);
  t->postTranslate(openvdb::Vec3d(3e9, 0, 0));
  grid->setTransform(t);
  const fs::path file = dir / "g.vdb";
  openvdb::io::File(file.string()).write({grid});
  std::string e = loadRefusal(file);
  EXPECT_NE(e.find("has a translation of 3e+09 along axis 0; coordinates must lie within +-100000"), std::string::npos) << e;
}

}  // namespace
