// btsm flash-firmware | keys: the per-device signing key, patched into the firmware image and
// kept in the host's key store.
#include "cmd_link_support.hpp"
#include "common/device_key.hpp"
#include "host/io/input_error.hpp"
#include "host/io/output_file.hpp"
#include "host/link/device_keys.hpp"
#include "host/link/firmware_image.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>

namespace btsm::cli {
namespace {

using namespace btsm::link;
using nlohmann::json;

// --- flash-firmware ------------------------------------------------------------------------------

struct FlashFirmwareArgs {
  LinkOptions link;
  std::string hex, out, device_id, avrdude = "avrdude";
  bool dry_run = false, new_key = false;
};

std::string default_hex_path() {
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) return (exe.parent_path() / "btsm-fw-bluno.hex").string();
  return "build/bin/btsm-fw-bluno.hex";
}

// The device's key from the store; with --new-key one is generated and stored first if it has
// none -- except in a dry run, which never changes the key store: then there is no key yet
// (nullopt) and nothing is patched.
std::optional<DeviceKey> key_for_device(const FlashFirmwareArgs& a, uint32_t id) {
  KeyStore ks = KeyStore::from_environment();
  if (!ks.exists(id)) {
    if (!a.new_key)
      throw CommandError(kExitUsage, fmt::format("no key for device {} in {}: pass --new-key, or `btsm keys import {} HEX`",
                                                 device_id_text(id), ks.dir(), device_id_text(id)));
    if (a.dry_run) {
      std::cerr << "flash-firmware: dry run: would generate and store a key " << ks.path_for(id)
                << " and write the image patched with it; nothing stored or written\n";
      return std::nullopt;
    }
    ks.save(id, KeyStore::generate());
    std::cerr << "flash-firmware: generated key " << ks.path_for(id) << "\n";
  }
  return ks.load(id);
}

// The image a Bluno takes through Optiboot: application flash only, below the 512-byte bootloader
// at 0x7E00 (the key record ends there). Data at or past it would overwrite the bootloader or
// fall off the 32 KiB part -- avrdude reports neither before writing.
HexImage read_application_image(const std::string& given) {
  const std::string path = given.empty() ? default_hex_path() : given;
  HexImage img;
  try {
    img = read_intel_hex(path);
  } catch (const io::InputError& e) {
    if (!given.empty()) throw;
    throw io::InputError(std::string(e.what()) + " (the build's image: build it with the firmware enabled, or pass --hex)");
  }
  constexpr uint32_t kBootloaderStart = device_key::kFlashAddress + device_key::kRecordSize;
  if (const auto first = img.bytes.lower_bound(kBootloaderStart); first != img.bytes.end())
    throw io::InputError(fmt::format("{}:{}: data at 0x{:04X}: an application image for the Bluno ends below the bootloader at "
                                      "0x{:04X} (32 KiB flash, 512 B Optiboot)",
                                      path, img.line_of(first->first), first->first, kBootloaderStart));
  return img;
}

// Patches the key record into the image and writes it (0600).
void write_patched_image(HexImage img, uint32_t id, const DeviceKey& key, const std::string& out) {
  const auto r = patch_device_key(img, id, key);
  if (r.had_key)
    std::cerr << fmt::format("flash-firmware: image already held a key for device {}; replaced\n",
                             device_id_text(r.previous_device_id));
  write_private_file(out, format_intel_hex(img));
  std::cerr << "flash-firmware: patched image " << out << " (device " << device_id_text(id) << ")\n";
}

void run_flash_firmware(const FlashFirmwareArgs& a) {
  const uint32_t id = parse_device_id_or_throw(a.device_id);
  check_link_syntax(a.link);  // `--usb xyz` was exit 3 (no device) here, exit 2 in info/record
  const std::string out = a.out.empty() ? "btsm-fw-" + device_id_text(id) + ".hex" : a.out;
  try {  // the patched image over its own input would replace the build's image with one module's key
    io::refuse_output_over_input(out, "--out", {a.hex.empty() ? default_hex_path() : a.hex, a.link.port});
    io::refuse_output_file_that_cannot_be_made(out, "--out", "patched firmware image");
  } catch (const std::exception& e) {
    throw CommandError(kExitUsage, e.what());
  }
  // Everything the arguments decide comes before a key is made or a keyed image written: the image
  // and the port (a BLE link or no link at all was found only after the patched image was on disk).
  const HexImage img = read_application_image(a.hex);
  const bool no_link_given = a.link.port.empty() && a.link.usb.empty() && a.link.ble.empty() && a.link.rfcomm.empty();
  const std::string port = a.dry_run && no_link_given ? std::string("PORT") : serial_port_for(spec_from(a.link));
  const std::optional<DeviceKey> key = key_for_device(a, id);
  if (key) write_patched_image(img, id, *key, out);
  const auto cmd = avrdude_command(port, out, a.avrdude);
  std::string line;
  for (const auto& s : cmd) line += (line.empty() ? "" : " ") + s;
  if (a.dry_run) {
    std::cout << line << "\n";
    return;
  }
  std::cerr << "flash-firmware: " << line << "\n";
  const int rc = run_command(cmd);
  if (rc != 0)
    throw CommandError(kExitDevice, fmt::format("avrdude failed (exit {}): check the port, that no other program "
                                                "(monitor, serial console) has it open, and that the board is a "
                                                "Bluno/Uno with Optiboot ('not in sync' = wrong port or baud)",
                                                rc));
  std::cerr << "flash-firmware: done; `btsm info` should now show device " << device_id_text(id) << "\n";
}

void register_flash_firmware(CLI::App& app) {
  auto a = std::make_shared<FlashFirmwareArgs>();
  auto* c = app.add_subcommand("flash-firmware", "Patch the device key into the firmware image and program it with avrdude");
  c->footer(
      "Writes the 64-byte key record (common/device_key.hpp: magic, device id, 32-byte key, CRC-32)\n"
      "at flash 0x7DC0 of the image, saves the patched image (mode 0600: it holds the key), then runs\n"
      "  avrdude -p atmega328p -c arduino -b 115200 -P PORT -D -U flash:w:PATCHED:i\n"
      "(the Bluno is programmed like an Arduino Uno through its USB port). The key is taken from the\n"
      "key store for --device-id; --new-key generates and stores one first. --dry-run changes no key:\n"
      "it writes the patched image (when the device has a key) and prints the command without running it.\n"
      "  btsm flash-firmware --device-id 0000de71 --new-key --port /dev/ttyACM0");
  add_link_options(*c, a->link);
  c->add_option("--device-id", a->device_id, "device id to give this module (hex, e.g. 0000de71)")->required();
  c->add_option("--hex", a->hex, "firmware image (default: btsm-fw-bluno.hex next to btsm)");
  c->add_option("--out", a->out, "patched image path (default: btsm-fw-<device_id>.hex in the current directory)");
  c->add_flag("--new-key", a->new_key, "generate and store a key for this device id if it has none");
  c->add_flag("--dry-run", a->dry_run, "patch and print the avrdude command, do not run it");
  c->add_option("--avrdude", a->avrdude, "avrdude executable")->capture_default_str();
  c->callback([a] { guarded([&] { run_flash_firmware(*a); }); });
}

// --- keys ----------------------------------------------------------------------------------------

void run_keys_list(bool as_json) {
  const KeyStore ks = KeyStore::from_environment();
  json j = json::array();
  for (uint32_t id : ks.list()) {
    // A listed key is one flash-model can use: a file it would refuse (open to others, not a
    // regular file, not 64 hex digits) is listed with the reason, not as a key.
    std::string problem;
    try {
      (void)ks.load(id);
    } catch (const std::exception& e) {
      problem = e.what();
    }
    if (as_json) {
      json e{{"device_id", device_id_text(id)}, {"path", ks.path_for(id)}, {"usable", problem.empty()}};
      if (!problem.empty()) e["problem"] = problem;
      j.push_back(e);
    } else {
      std::cout << device_id_text(id) << "  " << ks.path_for(id) << (problem.empty() ? "" : "  UNUSABLE: " + problem) << "\n";
    }
  }
  if (as_json) print_json(j);
}

struct KeyGenerateArgs {
  std::string id;
  bool force = false;
};

void run_keys_generate(const KeyGenerateArgs& a) {
  const KeyStore ks = KeyStore::from_environment();
  const uint32_t id = parse_device_id_or_throw(a.id);
  ks.save(id, KeyStore::generate(), a.force);
  std::cout << ks.path_for(id) << "\n";
}

struct KeyImportArgs {
  std::string id, hex;
  bool force = false;
};

void run_keys_import(const KeyImportArgs& a) {
  const auto key = key_from_hex(a.hex);
  if (!key) throw CommandError(kExitUsage, "key must be 64 hex characters (32 bytes)");
  // All 00 or all FF is what an erased or never-written key record reads as, not a secret: a
  // module "signed" with it accepts a model from anyone who guesses that.
  for (const uint8_t blank : {uint8_t{0x00}, uint8_t{0xFF}})
    if (std::all_of(key->begin(), key->end(), [blank](uint8_t b) { return b == blank; }))
      throw CommandError(kExitUsage, fmt::format("key is all {:02X} bytes, what blank memory reads as, not a secret: use "
                                                 "the module's real key, or `btsm keys generate ID` for a new one",
                                                 blank));
  const KeyStore ks = KeyStore::from_environment();
  const uint32_t id = parse_device_id_or_throw(a.id);
  ks.save(id, *key, a.force);
  std::cout << ks.path_for(id) << "\n";
}

void register_keys(CLI::App& app) {
  auto* k = app.add_subcommand("keys", "Manage per-device model-signing keys ($XDG_CONFIG_HOME/btsm/keys)");
  k->footer(
      "One file per module, <device_id>.key, 64 hex characters (32-byte HMAC-SHA256 key). Directory 0700,\n"
      "files 0600; a key file readable or writable by others is refused.");
  k->require_subcommand(1);
  k->add_subcommand("path", "Print the key directory")->callback([] {
    guarded([] { std::cout << KeyStore::from_environment().dir() << "\n"; });
  });

  auto json_list = std::make_shared<bool>(false);
  auto* list = k->add_subcommand("list", "List device ids that have a key");
  list->add_flag("--json", *json_list, "print as JSON");
  list->callback([json_list] { guarded([&] { run_keys_list(*json_list); }); });

  auto show_id = std::make_shared<std::string>();
  auto* show = k->add_subcommand("show", "Print a device's key (hex) — treat the output as a secret");
  show->add_option("id", *show_id, "device id (hex)")->required();
  show->callback([show_id] {
    guarded([&] { std::cout << key_to_hex(KeyStore::from_environment().load(parse_device_id_or_throw(*show_id))) << "\n"; });
  });

  auto gen = std::make_shared<KeyGenerateArgs>();
  auto* g = k->add_subcommand("generate", "Create a random key for a device id (refuses to overwrite unless --force)");
  g->add_option("id", gen->id, "device id (hex)")->required();
  g->add_flag("--force", gen->force, "replace an existing key (modules flashed with the old one will refuse models)");
  g->callback([gen] { guarded([&] { run_keys_generate(*gen); }); });

  auto imp = std::make_shared<KeyImportArgs>();
  auto* i = k->add_subcommand("import", "Store a key given as 64 hex characters for a device id");
  i->add_option("id", imp->id, "device id (hex)")->required();
  i->add_option("hex", imp->hex, "the key, 64 hex characters")->required();
  i->add_flag("--force", imp->force, "replace an existing key");
  i->callback([imp] { guarded([&] { run_keys_import(*imp); }); });
}

}  // namespace

void register_link_firmware_commands(CLI::App& app) {
  register_flash_firmware(app);
  register_keys(app);
}

}  // namespace btsm::cli
