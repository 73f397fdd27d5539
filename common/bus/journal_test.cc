#include "common/bus/journal.h"
#include "tests/testing/scratch.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

namespace fs = std::filesystem;

class JournalTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::anchormap::testing::ScratchDir() / "journal";
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Appends events 0..n-1: channel "C<i>", utime 100 i, i + 1 bytes of value i.
  static void AppendEvents(Journal* journal, int first, int n) {
    for (int i = first; i < first + n; ++i) {
      const std::vector<uint8_t> data(static_cast<size_t>(i + 1), static_cast<uint8_t>(i));
      ASSERT_TRUE(journal->Append("C" + std::to_string(i), 100 * i, data.data(), data.size()).ok());
    }
  }
  static void ExpectEvents(const std::vector<LogEvent>& events, int n) {
    ASSERT_EQ(static_cast<int>(events.size()), n);
    for (int i = 0; i < n; ++i) {
      EXPECT_EQ(events[i].channel, "C" + std::to_string(i));
      EXPECT_EQ(events[i].utime, 100 * i);
      EXPECT_EQ(events[i].data,
                std::vector<uint8_t>(static_cast<size_t>(i + 1), static_cast<uint8_t>(i)));
    }
  }

  fs::path dir_;
};

TEST_F(JournalTest, AppendedEventsAreReadBackAfterReopening) {
  std::vector<LogEvent> existing;
  {
    auto journal = Journal::Open(dir_.string(), &existing);
    ASSERT_TRUE(journal.ok()) << journal.status().message();
    EXPECT_TRUE(existing.empty());
    AppendEvents(journal->get(), 0, 5);
    EXPECT_EQ((*journal)->events(), 5);
    // Flushed: the bytes are in the file before the journal is closed.
    EXPECT_EQ(static_cast<int64_t>(fs::file_size((*journal)->path())), (*journal)->bytes());
  }
  {
    auto journal = Journal::Open(dir_.string(), &existing);
    ASSERT_TRUE(journal.ok());
    ExpectEvents(existing, 5);
    AppendEvents(journal->get(), 5, 3);
  }
  auto journal = Journal::Open(dir_.string(), &existing);
  ASSERT_TRUE(journal.ok());
  ExpectEvents(existing, 8);
  EXPECT_EQ((*journal)->events(), 8);
}

TEST_F(JournalTest, ACutShortLastEventIsDroppedAndAppendingContinues) {
  std::vector<LogEvent> existing;
  std::string path;
  {
    auto journal = Journal::Open(dir_.string(), &existing);
    ASSERT_TRUE(journal.ok());
    AppendEvents(journal->get(), 0, 4);
    path = (*journal)->path();
  }
  // Event 3 is 28 + 2 + 4 bytes: cut its last 3.
  fs::resize_file(path, fs::file_size(path) - 3);
  {
    auto journal = Journal::Open(dir_.string(), &existing);
    ASSERT_TRUE(journal.ok()) << journal.status().message();
    ExpectEvents(existing, 3);
    AppendEvents(journal->get(), 3, 2);
  }
  auto journal = Journal::Open(dir_.string(), &existing);
  ASSERT_TRUE(journal.ok());
  ExpectEvents(existing, 5);
}

TEST_F(JournalTest, CorruptionBeforeTheEndIsRefused) {
  std::vector<LogEvent> existing;
  std::string path;
  {
    auto journal = Journal::Open(dir_.string(), &existing);
    ASSERT_TRUE(journal.ok());
    AppendEvents(journal->get(), 0, 4);
    path = (*journal)->path();
  }
  {
    std::fstream file(path, std::ios::in | std::ios::out | std::ios::binary);
    file.seekp(0);
    file.put(0);  // event 0's sync word
  }
  auto journal = Journal::Open(dir_.string(), &existing);
  ASSERT_FALSE(journal.ok());
  EXPECT_EQ(journal.status().code(), ErrorCode::kIoError);
  EXPECT_NE(journal.status().message().find("corrupt"), std::string::npos);
}

TEST_F(JournalTest, OneProcessAtATime) {
  std::vector<LogEvent> existing;
  {
    auto first = Journal::Open(dir_.string(), &existing);
    ASSERT_TRUE(first.ok());
    AppendEvents(first->get(), 0, 2);
    // A second opener (another server on the same directory) is refused while it lives.
    auto second = Journal::Open(dir_.string(), &existing);
    ASSERT_FALSE(second.ok());
    EXPECT_NE(second.status().message().find("in use"), std::string::npos);
  }
  auto again = Journal::Open(dir_.string(), &existing);
  ASSERT_TRUE(again.ok()) << again.status().message();
  ExpectEvents(existing, 2);
}

TEST_F(JournalTest, AnUncreatableDirectoryIsAnError) {
  std::vector<LogEvent> existing;
  EXPECT_FALSE(Journal::Open("/proc/anchormap_no_such_dir/x", &existing).ok());
}

}  // namespace
}  // namespace anchormap
