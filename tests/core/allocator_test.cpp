#include "core/allocator.h"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <string>

namespace rangebayes {
namespace {

// Restores GLIBC_TUNABLES as the test found it.
class TunablesEnvironment : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* value = getenv("GLIBC_TUNABLES");
    had_ = value != nullptr;
    if (had_) saved_ = value;
  }
  void TearDown() override {
    if (had_) {
      setenv("GLIBC_TUNABLES", saved_.c_str(), 1);
    } else {
      unsetenv("GLIBC_TUNABLES");
    }
  }

 private:
  bool had_ = false;
  std::string saved_;
};

TEST_F(TunablesEnvironment, AppliesWithoutMallocTunables) {
  unsetenv("GLIBC_TUNABLES");
  EXPECT_EQ(ConfigureMallocForRepeatedBuffers(), MallocConfiguration::kApplied);
  setenv("GLIBC_TUNABLES", "glibc.pthread.rseq=0", 1);  // another namespace: not a malloc choice
  EXPECT_EQ(ConfigureMallocForRepeatedBuffers(), MallocConfiguration::kApplied);
}

TEST_F(TunablesEnvironment, KeepsTheUsersMallocTunables) {
  setenv("GLIBC_TUNABLES", "glibc.pthread.rseq=0:glibc.malloc.trim_threshold=1000000", 1);
  EXPECT_EQ(ConfigureMallocForRepeatedBuffers(), MallocConfiguration::kUserTunables);
}

}  // namespace
}  // namespace rangebayes
