// Device key store in a temporary HOME: locations, permissions, refusal of exposed keys.
#include "host/link/device_keys.hpp"
#include "link_test_support.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cstdlib>
#include <fstream>

using namespace btsm::link;

namespace {
mode_t mode_of(const std::string& p) {
  struct stat st {};
  ::stat(p.c_str(), &st);
  return st.st_mode & 07777;
}

struct EnvGuard {
  std::string name;
  std::optional<std::string> old;
  EnvGuard(const char* n, const char* value) : name(n) {
    if (const char* v = std::getenv(n)) old = v;
    if (value) ::setenv(n, value, 1);
    else ::unsetenv(n);
  }
  ~EnvGuard() {
    if (old) ::setenv(name.c_str(), old->c_str(), 1);
    else ::unsetenv(name.c_str());
  }
};
}  // namespace

TEST(KeyStore, LocationFollowsXdgThenHome) {
  btsm::test::TempDir home;
  EnvGuard h("HOME", home.path.c_str());
  {
    EnvGuard x("XDG_CONFIG_HOME", nullptr);
    EXPECT_EQ(KeyStore::from_environment().dir(), home.path + "/.config/btsm/keys");
  }
  {
    EnvGuard x("XDG_CONFIG_HOME", (home.path + "/cfg").c_str());
    EXPECT_EQ(KeyStore::from_environment().dir(), home.path + "/cfg/btsm/keys");
  }
}

TEST(KeyStore, GenerateSaveLoadWithStrictPermissions) {
  btsm::test::TempDir home;
  KeyStore ks(home.path + "/.config/btsm/keys");
  const DeviceKey k = KeyStore::generate();
  EXPECT_NE(k, DeviceKey{});
  EXPECT_NE(KeyStore::generate(), k);
  ks.save(0xDE71, k);
  EXPECT_EQ(mode_of(ks.dir()), 0700u);
  EXPECT_EQ(mode_of(ks.path_for(0xDE71)), 0600u);
  EXPECT_EQ(ks.path_for(0xDE71), ks.dir() + "/0000de71.key");
  EXPECT_EQ(ks.load(0xDE71), k);
  EXPECT_EQ(ks.list(), (std::vector<uint32_t>{0xDE71}));
  EXPECT_THROW(ks.save(0xDE71, KeyStore::generate()), std::runtime_error);  // no silent overwrite
  EXPECT_EQ(ks.load(0xDE71), k);
}

TEST(KeyStore, RefusesGroupOrWorldAccessibleKeyFiles) {
  btsm::test::TempDir home;
  KeyStore ks(home.path + "/keys");
  ks.save(7, KeyStore::generate());
  for (mode_t m : {0640, 0604, 0660, 0666, 0620}) {
    ::chmod(ks.path_for(7).c_str(), m);
    try {
      ks.load(7);
      FAIL() << std::oct << m;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("chmod 600"), std::string::npos) << e.what();
    }
  }
  ::chmod(ks.path_for(7).c_str(), 0400);
  EXPECT_NO_THROW(ks.load(7));
}

TEST(KeyStore, MalformedAndMissingKeysAreClearErrors) {
  btsm::test::TempDir home;
  KeyStore ks(home.path + "/keys");
  try {
    ks.load(0x1234);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("btsm keys generate 00001234"), std::string::npos) << e.what();
  }
  ks.save(1, KeyStore::generate());
  ::chmod(ks.path_for(1).c_str(), 0600);
  std::ofstream(ks.path_for(1)) << "abcd\n";
  EXPECT_THROW(ks.load(1), std::invalid_argument);
  EXPECT_FALSE(key_from_hex(std::string(63, 'a')));
  EXPECT_FALSE(key_from_hex(std::string(64, 'g')));
  EXPECT_TRUE(key_from_hex(std::string(64, 'A')));
  EXPECT_EQ(parse_device_id("0xDE70"), 0xDE70u);
  EXPECT_FALSE(parse_device_id("123456789"));
  EXPECT_FALSE(parse_device_id("xyz"));
}
