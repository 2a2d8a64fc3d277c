// USB adapter listing on a fake sysfs tree: cdc_acm (tty/ttyACMn) and usb-serial (ttyUSBn)
// layouts, a device without tty (driver missing / brltty), non-serial vendors ignored, RFCOMM.
#include "host/link/link_error.hpp"
#include "host/link/usb_devices.hpp"
#include "link_test_support.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

using namespace btsm::link;
namespace fs = std::filesystem;

namespace {

void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text << "\n";
}

// <root>/bus/usb/devices/<name>/{idVendor,idProduct,product,...} plus interface dirs.
void usb_device(const fs::path& root, const std::string& name, const std::string& vid, const std::string& pid,
                const std::string& product) {
  const fs::path d = root / "bus/usb/devices" / name;
  write(d / "idVendor", vid);
  write(d / "idProduct", pid);
  write(d / "product", product);
  write(d / "manufacturer", "Maker");
  write(d / "serial", "SN-" + name);
}

void fake_sysfs(const fs::path& root) {
  usb_device(root, "1-2", "2341", "0043", "Arduino Uno");
  fs::create_directories(root / "bus/usb/devices/1-2/1-2:1.0/tty/ttyACM0");
  fs::create_directories(root / "bus/usb/devices/1-2/1-2:1.1");
  fs::create_directories(root / "drivers/cdc_acm");
  fs::create_symlink(root / "drivers/cdc_acm", root / "bus/usb/devices/1-2/1-2:1.0/driver");

  usb_device(root, "1-1.4", "1a86", "7523", "USB Serial");
  fs::create_directories(root / "bus/usb/devices/1-1.4/1-1.4:1.0/ttyUSB0/tty/ttyUSB0");
  fs::create_directories(root / "drivers/ch341");
  fs::create_symlink(root / "drivers/ch341", root / "bus/usb/devices/1-1.4/1-1.4:1.0/driver");

  usb_device(root, "3-1", "10c4", "ea60", "CP2102");  // no tty bound
  fs::create_directories(root / "bus/usb/devices/3-1/3-1:1.0");

  usb_device(root, "2-3", "046d", "c52b", "Mouse");  // not a serial vendor
  fs::create_directories(root / "bus/usb/devices/usb1");  // root hub, no ids
  fs::create_directories(root / "bus/usb/devices/1-2:1.0");  // interface alias at top level
  fs::create_directories(root / "class/tty/rfcomm0");
  fs::create_directories(root / "class/tty/ttyS0");
}

}  // namespace

TEST(UsbDevices, ListsSerialAdaptersWithTheirTtys) {
  btsm::test::TempDir dir;
  fake_sysfs(dir.path);
  const auto ids = sysfs_usb_ids(dir.path);
  ASSERT_EQ(ids.size(), 4u);
  EXPECT_EQ(ids[0].sysfs_name(), "1-1.4");
  EXPECT_EQ(ids[0].ports, (std::vector<int>{1, 4}));
  const auto devs = describe_usb_serial(ids, dir.path, "/dev");
  ASSERT_EQ(devs.size(), 3u);  // the mouse is not listed
  const auto& ch340 = devs[0];
  EXPECT_EQ(ch340.vendor_kind, "CH340");
  EXPECT_EQ(ch340.ttys, (std::vector<std::string>{"/dev/ttyUSB0"}));
  EXPECT_EQ(ch340.driver, "ch341");
  const auto& uno = devs[1];
  EXPECT_EQ(uno.vendor_kind, "Arduino");
  EXPECT_EQ(uno.ttys, (std::vector<std::string>{"/dev/ttyACM0"}));
  EXPECT_EQ(uno.driver, "cdc_acm");
  EXPECT_EQ(uno.product, "Arduino Uno");
  EXPECT_EQ(uno.serial, "SN-1-2");
  const auto& cp = devs[2];
  EXPECT_TRUE(cp.ttys.empty());
  EXPECT_NE(cp.note.find("brltty"), std::string::npos);
  EXPECT_EQ(rfcomm_ttys(dir.path), (std::vector<std::string>{"/dev/rfcomm0"}));
}

TEST(UsbDevices, UsbOptionResolvesToOneTtyOrExplains) {
  btsm::test::TempDir dir;
  fake_sysfs(dir.path);
  auto devs = describe_usb_serial(sysfs_usb_ids(dir.path), dir.path);
  EXPECT_EQ(tty_for_usb("2341:0043", devs), "/dev/ttyACM0");
  EXPECT_EQ(tty_for_usb("1A86:7523", devs), "/dev/ttyUSB0");
  auto expect_no_device = [&](const std::string& arg, const std::string& fragment) {
    try {
      tty_for_usb(arg, devs);
      FAIL() << arg;
    } catch (const LinkError& e) {
      EXPECT_EQ(e.kind(), LinkErrorKind::kNoDevice);
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  expect_no_device("0403:6001", "btsm list");
  expect_no_device("10c4:ea60", "no tty bound");
  expect_no_device("nonsense", "VID:PID");
  devs.push_back(devs[1]);  // a second Uno
  expect_no_device("2341:0043", "--port");
  EXPECT_FALSE(parse_vid_pid("2341"));
  EXPECT_FALSE(parse_vid_pid("12345:1"));
  EXPECT_EQ(parse_vid_pid("2341:43")->second, 0x43);
}

TEST(UsbDevices, LibusbEnumerationRunsOrFailsCleanly) {
  // On a build machine there may be no USB at all; either way no crash and no exception other
  // than a LinkError.
  try {
    const auto ids = libusb_ids();
    for (const auto& id : ids) EXPECT_GT(id.bus, 0);
  } catch (const LinkError&) {
  }
}
