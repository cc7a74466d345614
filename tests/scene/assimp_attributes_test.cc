// What the assimp reader keeps of an object besides its geometry: its source file, its node's metadata
// and, for IFC files, the entity's type, name and GlobalId.
#include <assimp/scene.h>  // metadata.h needs the types scene.h includes first
#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

#include "engine/scene/assimp_metadata.h"
#include "engine/scene/assimp_reader.h"
#include "scene/scene_test_util.h"

namespace mktree {
namespace {

std::string AttributeValue(const std::vector<ObjectAttribute>& attributes, const std::string& key) {
  for (const ObjectAttribute& a : attributes)
    if (a.key == key) return a.value;
  return "<missing>";
}

TEST(AssimpAttributesTest, IfcNodeNamesSplitIntoTypeNameAndGlobalId) {
  std::vector<ObjectAttribute> a;
  // GlobalIds use '_' and '$' too; the name between may hold '_' and ':'.
  ASSERT_TRUE(
      AppendIfcNameAttributes("IfcWallStandardCase_Basic_Wall:Brick:138062_2O2Fr$t4X7Zf8NOew3F_tn", &a));
  EXPECT_EQ(a, (std::vector<ObjectAttribute>{{"ifc_type", "IfcWallStandardCase"},
                                             {"ifc_name", "Basic_Wall:Brick:138062"},
                                             {"ifc_global_id", "2O2Fr$t4X7Zf8NOew3F_tn"}}));
  a.clear();
  ASSERT_TRUE(AppendIfcNameAttributes("IfcSlab__0123456789abcdefABCDEF", &a));
  EXPECT_EQ(AttributeValue(a, "ifc_name"), "");
  a.clear();
  EXPECT_FALSE(AppendIfcNameAttributes("Wall_0123456789abcdefABCDEF", &a));       // not an Ifc type
  EXPECT_FALSE(AppendIfcNameAttributes("IfcWall_0123456789abcdefABCDE", &a));     // no GlobalId
  EXPECT_FALSE(AppendIfcNameAttributes("IfcWall_x_0123456789abcdef-BCDEF", &a));  // '-' is not a GUID char
  EXPECT_FALSE(AppendIfcNameAttributes("IfcWall", &a));
  EXPECT_TRUE(a.empty());
}

TEST(AssimpAttributesTest, MetadataOfEveryTypeBecomesText) {
  aiMetadata* inner = aiMetadata::Alloc(1);
  inner->Set(0, "depth", 2.5);
  aiMetadata* m = aiMetadata::Alloc(7);
  m->Set(0, "flag", true);
  m->Set(1, "count", int32_t{-7});
  m->Set(2, "big", uint64_t{1} << 40);
  m->Set(3, "ratio", 0.1f);
  m->Set(4, "name", aiString(std::string("pump 3")));
  m->Set(5, "at", aiVector3D(1, -2, 0.5f));
  m->Set(6, "nested", *inner);
  std::vector<ObjectAttribute> a;
  AppendMetadataAttributes(*m, &a);
  EXPECT_EQ(a, (std::vector<ObjectAttribute>{{"flag", "true"},
                                             {"count", "-7"},
                                             {"big", "1099511627776"},
                                             {"ratio", "0.1"},
                                             {"name", "pump 3"},
                                             {"at", "1 -2 0.5"},
                                             {"nested.depth", "2.5"}}));
  delete m;
  delete inner;
}

// The IFC files: every object is an IFC product, or a mapped representation (IfcMappedItem) of one, and
// carries the product's type, GlobalId and property sets.
class IfcAttributesTest : public ::testing::TestWithParam<const char*> {};

TEST_P(IfcAttributesTest, ObjectsCarryTheirProductsTypeGlobalIdAndProperties) {
  const std::string path = std::string(MKTREE_SHARED_DATA) + "/" + GetParam();
  auto r = ReadAllFrom(OpenAssimpFile(path, 0));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_FALSE(r->empty());
  std::set<std::string> product_ids;
  size_t walls = 0, mapped = 0;
  for (const SceneObject& o : *r) {
    EXPECT_EQ(o.source, path);
    const std::string type = AttributeValue(o.attributes, "ifc_type");
    ASSERT_EQ(type.rfind("Ifc", 0), 0u) << o.name;
    const std::string id = AttributeValue(o.attributes, "ifc_global_id");
    EXPECT_EQ(id.size(), 22u) << o.name;
    if (o.name == "IfcMappedItem") {
      ++mapped;
    } else {
      EXPECT_TRUE(product_ids.insert(id).second) << "GlobalId " << id << " on two products";
      EXPECT_EQ(o.name, type + "_" + AttributeValue(o.attributes, "ifc_name") + "_" + id);
    }
    if (type == "IfcWallStandardCase") {
      ++walls;
      EXPECT_NE(AttributeValue(o.attributes, "LoadBearing"), "<missing>") << o.name;
    }
  }
  EXPECT_GT(walls, 10u);
  EXPECT_GT(mapped, 10u);
}

INSTANTIATE_TEST_SUITE_P(SharedData, IfcAttributesTest,
                         ::testing::Values("buildings/duplex.ifc", "buildings/Office_A_20110811.ifc"));

}  // namespace
}  // namespace mktree
