// FetchedFiles (client/farm_client.h): how the client writes the files it
// fetches, over gRPC (FarmClient::fetch) or from the embedded farm's
// coordinator by a call (LocalFarm::fetch). Whole files appear only once
// their last chunk is written; a name that is not a plain file name, a
// chunk out of order or a file that cannot be written stops it, names the
// problem, and leaves no partial file behind.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "client/farm_client.h"

namespace locus::client {
namespace {

namespace fs = std::filesystem;

class FetchedFilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("locus-fetched-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            "-" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Where frame f goes: <dir>/out_<f>.bin (a sub-folder for frame 3).
  FileDest dest() {
    return [this](int frame, const std::string&) {
      const fs::path p = frame == 3 ? dir_ / "sub" / "out_3.bin"
                                    : dir_ / ("out_" + std::to_string(frame) + ".bin");
      return p.string();
    };
  }
  static farm::FileChunk chunk(int frame, int64_t offset, const std::string& data, bool last,
                               const std::string& name = "shot_0001.exr") {
    farm::FileChunk c;
    c.frame = frame;
    c.file_name = name;
    c.offset = offset;
    c.data = data;
    c.last = last;
    return c;
  }
  static std::string read(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
  }
  // Every file left in the directory, as "name" or "sub/name".
  std::vector<std::string> files() const {
    std::vector<std::string> out;
    for (const auto& e : fs::recursive_directory_iterator(dir_)) {
      if (e.is_regular_file()) out.push_back(fs::relative(e.path(), dir_).string());
    }
    std::sort(out.begin(), out.end());
    return out;
  }

  fs::path dir_;
};

TEST_F(FetchedFilesTest, ChunksBecomeWholeFilesInOrder) {
  FetchedFiles f(dest(), "test");
  EXPECT_TRUE(f.take(chunk(1, 0, "abc", false)));
  // Not there until its last chunk: only the .partial.
  EXPECT_FALSE(fs::exists(dir_ / "out_1.bin"));
  EXPECT_TRUE(fs::exists(dir_ / "out_1.bin.partial"));
  EXPECT_TRUE(f.take(chunk(1, 3, "defg", true)));
  EXPECT_TRUE(f.take(chunk(3, 0, "xyz", true)));  // its folder made
  ASSERT_TRUE(f.status().ok()) << f.status().message();
  EXPECT_EQ(read(dir_ / "out_1.bin"), "abcdefg");
  EXPECT_EQ(read(dir_ / "sub" / "out_3.bin"), "xyz");
  EXPECT_EQ(f.written(), (std::vector<std::string>{(dir_ / "out_1.bin").string(),
                                                   (dir_ / "sub" / "out_3.bin").string()}));
  EXPECT_EQ(files(), (std::vector<std::string>{"out_1.bin", "sub/out_3.bin"}));
}

TEST_F(FetchedFilesTest, AnEmptyFileIsWritten) {
  FetchedFiles f(dest(), "test");
  EXPECT_TRUE(f.take(chunk(2, 0, "", true)));
  ASSERT_TRUE(f.status().ok()) << f.status().message();
  EXPECT_TRUE(fs::exists(dir_ / "out_2.bin"));
  EXPECT_EQ(fs::file_size(dir_ / "out_2.bin"), 0u);
}

TEST_F(FetchedFilesTest, ANameThatIsNotAPlainFileNameIsRefusedBeforeAnythingIsWritten) {
  for (const std::string& name :
       std::vector<std::string>{"../evil.exr", "a/b.exr", "", "..", "x\ny.exr"}) {
    FetchedFiles f(dest(), "coordinator 127.0.0.1:1");
    EXPECT_FALSE(f.take(chunk(1, 0, "abc", true, name))) << name;
    EXPECT_EQ(f.status().code(), Code::kInvalidArgument) << name;
    EXPECT_NE(f.status().message().find("coordinator 127.0.0.1:1 sent a file"), std::string::npos)
        << f.status().message();
    EXPECT_NE(f.status().message().find("is not a plain file name"), std::string::npos);
    // Stopped: a good chunk after it is not taken either.
    EXPECT_FALSE(f.take(chunk(2, 0, "abc", true)));
    EXPECT_TRUE(f.written().empty());
  }
  EXPECT_TRUE(files().empty());
}

TEST_F(FetchedFilesTest, AChunkOutOfOrderStopsItAndLeavesNoPartialFile) {
  {
    FetchedFiles f(dest(), "test");
    EXPECT_TRUE(f.take(chunk(1, 0, "abc", true)));
    EXPECT_TRUE(f.take(chunk(2, 0, "abc", false)));
    EXPECT_FALSE(f.take(chunk(2, 5, "def", true)));  // a gap: 3 expected
    EXPECT_EQ(f.status().code(), Code::kInternal);
    EXPECT_NE(f.status().message().find("frame 2 arrived out of order"), std::string::npos)
        << f.status().message();
    EXPECT_EQ(f.written(), std::vector<std::string>{(dir_ / "out_1.bin").string()});
  }
  // The whole file stays; the half-written one's .partial is gone.
  EXPECT_EQ(files(), std::vector<std::string>{"out_1.bin"});
  // A stream that starts past 0 has no file to go on.
  FetchedFiles g(dest(), "test");
  EXPECT_FALSE(g.take(chunk(4, 10, "abc", true)));
  EXPECT_EQ(g.status().code(), Code::kInternal);
}

TEST_F(FetchedFilesTest, AFileThatCannotBeWrittenIsNamed) {
  // Its folder is a file: neither the folder nor the file can be made.
  std::ofstream(dir_ / "sub") << "in the way";
  FetchedFiles f(dest(), "test");
  EXPECT_FALSE(f.take(chunk(3, 0, "abc", true)));
  EXPECT_EQ(f.status().code(), Code::kFailedPrecondition);
  EXPECT_NE(f.status().message().find((dir_ / "sub" / "out_3.bin").string() + ": cannot write"),
            std::string::npos)
      << f.status().message();
  EXPECT_TRUE(f.written().empty());
  EXPECT_EQ(files(), std::vector<std::string>{"sub"});
}

TEST_F(FetchedFilesTest, AWriterDroppedMidFileRemovesItsPartialFile) {
  {
    FetchedFiles f(dest(), "test");
    EXPECT_TRUE(f.take(chunk(1, 0, "abc", false)));
    EXPECT_TRUE(fs::exists(dir_ / "out_1.bin.partial"));
  }
  EXPECT_TRUE(files().empty());
}

}  // namespace
}  // namespace locus::client
