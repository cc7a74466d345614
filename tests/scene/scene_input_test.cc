// Every scene reader refuses what is not a regular file, at once: a FIFO (opening one for reading would wait
// for a writer), a directory, a device.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>

#include "engine/scene/mkscene_format.h"
#include "engine/scene/obj_reader.h"
#include "engine/scene/scene_source.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

TEST(SceneInputTest, NonRegularFilesAreRefusedWithoutBlocking) {
  const testing::TempDir dir("mktree_scene_input");
  fs::create_directories(dir / "scene.obj");  // a directory named like a scene
  for (const char* name : {"fifo.obj", "fifo.mks", "fifo.ply"})
    ASSERT_EQ(::mkfifo((dir / name).c_str(), 0600), 0) << name;
  const std::string inputs[] = {(dir / "fifo.obj").string(), (dir / "fifo.mks").string(),
                                (dir / "fifo.ply").string(), (dir / "scene.obj").string(), "/dev/null"};
  for (const std::string& path : inputs) {
    auto opened = OpenSceneFile(path, 0);
    ASSERT_FALSE(opened.ok()) << path;
    EXPECT_EQ(opened.status().message(), path + ": not a regular file") << opened.status().ToString();
  }
  // The format readers on their own, as library users call them.
  EXPECT_FALSE(OpenObjFile((dir / "fifo.obj").string()).ok());
  EXPECT_FALSE(OpenMkSceneFile((dir / "fifo.mks").string()).ok());
  EXPECT_EQ(OpenObjFile((dir / "missing.obj").string()).status().code(), Status::Code::kNotFound);
}

}  // namespace
}  // namespace mktree
