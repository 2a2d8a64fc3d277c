// Writes the libFuzzer seed corpus for wire_fuzz: valid encoded frames of every message type
// (alone, back to back, with garbage around them) and [type][seq][payload] inputs for the frame
// path. Usage: wire_fuzz_seeds <seed_dir> <work_dir>; work_dir is emptied so every ctest run
// starts from the same corpus.
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

#include "wire_test_support.hpp"

namespace fs = std::filesystem;
using btsm::wire::testing::Bytes;

namespace {
void write(const fs::path& dir, const std::string& name, const Bytes& b) {
  std::ofstream f(dir / name, std::ios::binary);
  f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  if (!f) throw std::runtime_error("cannot write seed " + (dir / name).string());
}
}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: wire_fuzz_seeds <seed_dir> <work_dir>\n";
    return 2;
  }
  try {
    const fs::path seeds = argv[1];
    const fs::path work = argv[2];
    fs::remove_all(seeds);
    fs::remove_all(work);
    fs::create_directories(seeds);
    fs::create_directories(work);
    const auto frames = btsm::wire::testing::representative_frames();
    Bytes all;
    int count = 0;
    for (const auto& f : frames) {
      const Bytes w = f.wire();
      write(seeds, "frame_" + f.name, w);
      Bytes typed = {f.type, f.seq};
      typed.insert(typed.end(), f.payload.begin(), f.payload.end());
      write(seeds, "typed_" + f.name, typed);
      all.insert(all.end(), w.begin(), w.end());
      Bytes noisy = {0x00, 0x2B, 0x7D};
      noisy.insert(noisy.end(), w.begin(), w.end());
      noisy.insert(noisy.end(), {0x7E, 0x01, 0x7E});
      write(seeds, "noisy_" + f.name, noisy);
      count += 3;
    }
    write(seeds, "stream_all", all);
    std::cout << "wrote " << count + 1 << " seeds to " << seeds << "\n";
  } catch (const std::exception& e) {
    std::cerr << "wire_fuzz_seeds: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
