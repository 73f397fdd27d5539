#include "server/node/snapshot_store.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "tests/testing/scratch.h"

namespace anchormap {
namespace {

TEST(SnapshotStoreTest, SnapshotsAreListedNewestFirstAndOnlyTheNewestKept) {
  const std::string dir = testing::ScratchPath("snapshot_store");
  std::filesystem::create_directories(dir);
  const std::vector<uint8_t> a = {1, 2, 3};
  const std::vector<uint8_t> b = {4, 5};
  const std::vector<uint8_t> c(100000, 7);
  ASSERT_TRUE(WriteSnapshotFile(dir, 900, a, 2).ok());
  ASSERT_TRUE(WriteSnapshotFile(dir, 10000, b, 2).ok());  // more digits: still sorted by number
  {
    std::ofstream(dir + "/snapshot.tmp") << "a half-written snapshot";  // a crash mid-write
    std::ofstream(dir + "/snapshot-12x.bin") << "not one of ours";
  }
  std::vector<std::string> files = ListSnapshotFiles(dir);
  ASSERT_EQ(files.size(), 2u);
  EXPECT_EQ(std::filesystem::path(files[0]).filename(), "snapshot-000000010000.bin");
  EXPECT_EQ(std::filesystem::path(files[1]).filename(), "snapshot-000000000900.bin");
  ASSERT_TRUE(WriteSnapshotFile(dir, 20000, c, 2).ok());
  files = ListSnapshotFiles(dir);
  ASSERT_EQ(files.size(), 2u);  // the oldest removed
  const Result<std::vector<uint8_t>> newest = ReadSnapshotFile(files[0]);
  ASSERT_TRUE(newest.ok());
  EXPECT_EQ(*newest, c);
  const Result<std::vector<uint8_t>> previous = ReadSnapshotFile(files[1]);
  ASSERT_TRUE(previous.ok());
  EXPECT_EQ(*previous, b);
  EXPECT_FALSE(std::filesystem::exists(dir + "/snapshot.tmp"));  // replaced, then renamed
  EXPECT_FALSE(ReadSnapshotFile(dir + "/snapshot-000000000001.bin").ok());
  EXPECT_FALSE(WriteSnapshotFile(dir + "/missing", 1, a, 2).ok());
}

}  // namespace
}  // namespace anchormap
