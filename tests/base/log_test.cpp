#include "common/base/log.h"

#include <gtest/gtest.h>
#include <spdlog/details/log_msg.h>

#include <regex>
#include <string>

namespace locus {
namespace {

std::string format(LogFormat f, std::string_view text,
                   spdlog::level::level_enum level = spdlog::level::info) {
  auto formatter = make_log_formatter(f);
  spdlog::details::log_msg msg("locus", level, spdlog::string_view_t(text.data(), text.size()));
  spdlog::memory_buf_t buf;
  formatter->format(msg, buf);
  return std::string(buf.data(), buf.size());
}

TEST(Log, JsonEscape) {
  EXPECT_EQ(json_escape("plain"), "plain");
  EXPECT_EQ(json_escape("say \"hi\"\\"), "say \\\"hi\\\"\\\\");
  EXPECT_EQ(json_escape("a\nb\tc\rd"), "a\\nb\\tc\\rd");
  EXPECT_EQ(json_escape(std::string("\x01\x1f\x7f", 3)), "\\u0001\\u001f\\u007f");
  EXPECT_EQ(json_escape(std::string("nul\0end", 7)), "nul\\u0000end");
  // Valid UTF-8 passes; bytes that start no valid sequence become U+FFFD.
  EXPECT_EQ(json_escape("caf\xC3\xA9 \xE2\x82\xAC \xF0\x9F\x8E\xA5"),
            "caf\xC3\xA9 \xE2\x82\xAC \xF0\x9F\x8E\xA5");
  EXPECT_EQ(json_escape("\xFF"), "\xEF\xBF\xBD");
  EXPECT_EQ(json_escape("\xC3"), "\xEF\xBF\xBD");                                  // truncated
  EXPECT_EQ(json_escape("\xC0\xAF"), "\xEF\xBF\xBD\xEF\xBF\xBD");                  // overlong '/'
  EXPECT_EQ(json_escape("\xED\xA0\x80"), "\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBD");  // surrogate
}

TEST(Log, ParseFormat) {
  EXPECT_EQ(*parse_log_format("text"), LogFormat::kText);
  EXPECT_EQ(*parse_log_format("json"), LogFormat::kJson);
  auto bad = parse_log_format("yaml");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("--log-format 'yaml'"), std::string::npos);
  EXPECT_FALSE(setup_logging(LogFormat::kText, "loud").ok());
}

TEST(Log, JsonLineWithoutBand) {
  const std::string line = format(LogFormat::kJson, "worker w0001 registered", spdlog::level::warn);
  EXPECT_TRUE(std::regex_match(
      line, std::regex(R"(\{"time":"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z","level":"warning",)"
                       R"("logger":"locus","msg":"worker w0001 registered"\}\n)")))
      << line;
}

TEST(Log, JsonLineCarriesBandIdsAndEscapes) {
  std::string line;
  {
    BandLogScope scope("j0007", 3, 12);
    line = format(LogFormat::kJson, "bad \"pixels\"\nnext line");
  }
  EXPECT_NE(line.find(R"("msg":"bad \"pixels\"\nnext line","job":"j0007","frame":3,"band":12})"),
            std::string::npos)
      << line;
  EXPECT_EQ(line.find('\n'), line.size() - 1) << "one object per line";
  // Out of scope: no ids.
  EXPECT_EQ(format(LogFormat::kJson, "x").find("\"job\""), std::string::npos);
}

TEST(Log, NestedScopesRestoreTheOuterIds) {
  BandLogScope job("j0001");
  {
    BandLogScope band("j0001", 2, 5);
    EXPECT_NE(format(LogFormat::kText, "m").find("[job j0001 frame 2 band 5] m"),
              std::string::npos);
  }
  const std::string outer = format(LogFormat::kText, "m");
  EXPECT_NE(outer.find("[job j0001] m"), std::string::npos) << outer;
  EXPECT_EQ(format(LogFormat::kJson, "m").find("\"frame\""), std::string::npos);
}

}  // namespace
}  // namespace locus
