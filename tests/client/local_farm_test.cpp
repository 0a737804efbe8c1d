// The embedded farm's choice of who compresses an EXR job's blocks
// (client/local_farm.h, docs/farm.md "Frames"): its workers (exr+zip) when
// they fill the machine's cores, else its coordinator. Either way the file
// is the single-process render's, byte for byte (tests/farm_processes.sh,
// AnExrFrameIsWrittenFromZippedBandsOrElseStitched).
#include "client/local_farm.h"

#include <gtest/gtest.h>

namespace locus::client {
namespace {

TEST(LocalFarm, WorkersCompressTheirBlocksOnlyWhenTheyFillTheCores) {
  EXPECT_FALSE(local_farm_zips_exr(1, 1, 2));  // one worker, a core idle
  EXPECT_TRUE(local_farm_zips_exr(2, 1, 2));
  EXPECT_TRUE(local_farm_zips_exr(1, 2, 2));
  EXPECT_TRUE(local_farm_zips_exr(1, 0, 2));  // --threads 0: every core
  EXPECT_FALSE(local_farm_zips_exr(3, 1, 4));
  EXPECT_TRUE(local_farm_zips_exr(4, 1, 4));
  EXPECT_TRUE(local_farm_zips_exr(1, 1, 1));
}

}  // namespace
}  // namespace locus::client
