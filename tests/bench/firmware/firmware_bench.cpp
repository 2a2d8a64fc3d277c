// Firmware figures: flash/RAM use of the AVR image, CPU cycles per full 5-channel sample cycle
// measured in simavr (active cycles = not sleeping, with the sweep separated from the idle
// timer-tick load), the resulting CPU duty at the sample period, and the simulated-time speed-up
// of the simulated module on both boards. Prints figures; asserts nothing about time.
//   firmware_bench [path/to/btsm-fw-bluno.elf]
// Environment: BTSM_BENCH_VERBOSE=1 prints every sweep and the speed of every sample;
// BTSM_BENCH_PROFILE=1 attributes active cycles to the image's functions (by PC, from the ELF
// symbol table) and prints the top 15 functions of the worst sweep of each measurement (=N: top N).
#include "boards/sim/ad7794_model.hpp"
#include "host/sim/plant/probes.hpp"
#include "host/sim/runner/sim_module.hpp"
#include "boards/sim/simavr/simavr_harness.hpp"
#include "tests/bench/firmware/stack_paint.hpp"
#include "tests/hil/sim/model_upload.hpp"
#include "tests/simavr/sim/avr_link.hpp"

#include <elf.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <cxxabi.h>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <string>
#include <vector>

namespace {

struct SectionSizes {
  std::map<std::string, uint64_t> by_name;
  uint64_t flash = 0;  // allocated sections in program memory + .data initialisers
  uint64_t ram = 0;    // .data + .bss + .noinit
};

// Reads the ELF32 section table (AVR images are 32-bit little-endian ELF).
SectionSizes elf_sections(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> f((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (f.size() < sizeof(Elf32_Ehdr) || std::memcmp(f.data(), ELFMAG, SELFMAG) != 0 || f[EI_CLASS] != ELFCLASS32)
    throw std::runtime_error(path + ": not an ELF32 file");
  Elf32_Ehdr eh;
  std::memcpy(&eh, f.data(), sizeof eh);
  if (eh.e_shoff + size_t(eh.e_shnum) * sizeof(Elf32_Shdr) > f.size()) throw std::runtime_error(path + ": truncated");
  std::vector<Elf32_Shdr> sh(eh.e_shnum);
  std::memcpy(sh.data(), f.data() + eh.e_shoff, sh.size() * sizeof(Elf32_Shdr));
  const Elf32_Shdr& strtab = sh.at(eh.e_shstrndx);
  SectionSizes s;
  for (const auto& h : sh) {
    if (!(h.sh_flags & SHF_ALLOC) || h.sh_size == 0) continue;
    const std::string name = f.data() + strtab.sh_offset + h.sh_name;
    s.by_name[name] += h.sh_size;
    if (h.sh_addr >= 0x800000) {  // data address space (SRAM, EEPROM, fuses, .mmcu metadata)
      if (name == ".data" || name == ".bss" || name == ".noinit") s.ram += h.sh_size;
      if (name == ".data") s.flash += h.sh_size;  // initialisers are stored in flash
    } else {
      s.flash += h.sh_size;
    }
  }
  return s;
}

// Function symbols of an AVR image: a PC belongs to the nearest symbol at or below it (libgcc's
// assembler routines carry no size, so sizes are not relied on).
struct SymbolTable {
  std::vector<std::string> names;      // index 0: "(no symbol)"
  std::vector<uint32_t> index_by_word;  // flash word address -> index into names
};

SymbolTable elf_function_symbols(const std::string& path, size_t flash_words) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> f((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  Elf32_Ehdr eh;
  std::memcpy(&eh, f.data(), sizeof eh);
  std::vector<Elf32_Shdr> sh(eh.e_shnum);
  std::memcpy(sh.data(), f.data() + eh.e_shoff, sh.size() * sizeof(Elf32_Shdr));
  std::map<uint32_t, std::string> by_addr;  // one name per address: a FUNC wins over a label
  for (const auto& h : sh) {
    if (h.sh_type != SHT_SYMTAB) continue;
    const char* strtab = f.data() + sh.at(h.sh_link).sh_offset;
    for (size_t k = 0; k < h.sh_size / sizeof(Elf32_Sym); ++k) {
      Elf32_Sym sym;
      std::memcpy(&sym, f.data() + h.sh_offset + k * sizeof(Elf32_Sym), sizeof sym);
      const int type = ELF32_ST_TYPE(sym.st_info);
      if ((type != STT_FUNC && type != STT_NOTYPE) || sym.st_shndx == SHN_UNDEF || sym.st_shndx >= sh.size()) continue;
      if (!(sh[sym.st_shndx].sh_flags & SHF_EXECINSTR) || sym.st_value >= 0x800000) continue;
      std::string name = strtab + sym.st_name;
      if (name.empty() || name[0] == '.') continue;
      if (by_addr.count(sym.st_value) && type != STT_FUNC) continue;
      int status = 0;
      if (char* d = abi::__cxa_demangle(name.c_str(), nullptr, nullptr, &status)) {
        name = d;
        std::free(d);
      }
      by_addr[sym.st_value] = name;
    }
  }
  SymbolTable t;
  t.names.push_back("(no symbol)");
  t.index_by_word.assign(flash_words, 0);
  auto it = by_addr.begin();
  for (size_t w = 0; w < flash_words; ++w) {
    while (it != by_addr.end() && it->first <= 2 * w) {
      t.names.push_back(it->second);
      ++it;
    }
    t.index_by_word[w] = uint32_t(t.names.size() - 1);
  }
  return t;
}

// Sparse per-function active cycles of one 2 ms bin.
using BinProfile = std::vector<std::pair<uint32_t, uint64_t>>;

struct CycleFigures {
  double sweep_cycles = 0;        // mean active cycles per 5-channel sample cycle, idle load removed
  double sweep_cycles_max = 0;
  double speed_change_max = -1;   // max over the sweeps that see a new tach frequency (-1: none)
  std::vector<std::pair<std::string, double>> worst_profile;  // BTSM_BENCH_PROFILE: cycles by function
  double idle_cycles_per_s = 0;   // timer ticks etc. outside sweeps
  int stack_max = -1;             // deepest stack use, B (-1: not measured)
  int stack_margin = -1;          // SRAM between the end of .bss and the deepest stack write, B
  double period_s = 0;
  int sweeps = 0;
  uint64_t spi_bytes_per_sweep = 0;
};

// A tach frequency change during the measurement, `at_s` after its start.
struct TachChange {
  double at_s;
  double hz;
};

// Runs the image for `seconds` from `start_s` on, in 2 ms bins, applying `tach` changes. A sweep
// is the stretch from the first to the last SPI byte of a sample period plus 40 ms for the frame
// to be sent; a speed-change sweep is the first one that starts after a tach change.
CycleFigures measure_cycles(btsm::sim::SimavrHarness& h, const std::string& elf, double start_s, double seconds,
                            const std::vector<TachChange>& tach = {}) {
  const double bin = 0.002;
  std::vector<uint64_t> active, spi;
  std::vector<int> change_bins;
  std::vector<size_t> tach_phase;  // per bin: how many tach changes are in effect
  const bool profiling = std::getenv("BTSM_BENCH_PROFILE") != nullptr;
  std::vector<uint64_t> by_word;
  SymbolTable symbols;
  std::vector<uint64_t> by_symbol;
  std::vector<BinProfile> bin_profiles;
  h.run_until(start_s);
  if (profiling) {
    const size_t words = size_t(h.core()->flashend + 1) / 2;
    symbols = elf_function_symbols(elf, words);
    by_word.assign(words, 0);
    by_symbol.assign(symbols.names.size(), 0);
    h.set_profile(&by_word);
  }
  auto last = h.stats();
  const int bins = int(seconds / bin);
  size_t next_change = 0;
  for (int i = 0; i < bins; ++i) {
    if (next_change < tach.size() && tach[next_change].at_s <= i * bin) {
      h.set_tach_hz(tach[next_change++].hz);
      change_bins.push_back(i);
    }
    tach_phase.push_back(next_change);
    h.run_until(start_s + (i + 1) * bin);
    const auto s = h.stats();
    active.push_back(s.active_cycles() - last.active_cycles());
    spi.push_back(s.spi_bytes - last.spi_bytes);
    last = s;
    if (profiling) {
      BinProfile p;
      for (size_t w = 0; w < by_word.size(); ++w)
        if (by_word[w]) by_symbol[symbols.index_by_word[w]] += by_word[w], by_word[w] = 0;
      for (size_t k = 0; k < by_symbol.size(); ++k)
        if (by_symbol[k]) p.push_back({uint32_t(k), by_symbol[k]}), by_symbol[k] = 0;
      bin_profiles.push_back(std::move(p));
    }
  }
  h.set_profile(nullptr);
  // Group SPI activity into sweeps (gaps > 1 s separate sweeps).
  std::vector<std::pair<int, int>> sweeps;
  for (int i = 0; i < bins; ++i) {
    if (!spi[size_t(i)]) continue;
    if (!sweeps.empty() && i - sweeps.back().second < int(1.0 / bin)) sweeps.back().second = i;
    else sweeps.push_back({i, i});
  }
  std::vector<bool> in_sweep(size_t(bins), false);
  const int tail = int(0.040 / bin);
  for (auto& sw : sweeps) {
    sw.second = std::min(bins - 1, sw.second + tail);
    for (int i = sw.first; i <= sw.second; ++i) in_sweep[size_t(i)] = true;
  }
  // The idle load depends on the tach frequency (an interrupt per pulse): each sweep is charged
  // the idle load measured at its own tach frequency.
  // Bins before the first SPI byte are not idle time when the run starts at a reset (boot: crt
  // start-up, the stored model's validation): they count neither as idle nor as a sweep.
  const int first_spi = sweeps.empty() ? bins : sweeps.front().first;
  std::vector<double> idle_active(tach.size() + 1, 0.0);
  std::vector<int> idle_bins(tach.size() + 1, 0);
  for (int i = first_spi; i < bins; ++i)
    if (!in_sweep[size_t(i)]) idle_active[tach_phase[size_t(i)]] += double(active[size_t(i)]), ++idle_bins[tach_phase[size_t(i)]];
  CycleFigures c;
  const int all_idle_bins = std::accumulate(idle_bins.begin(), idle_bins.end(), 0);
  c.idle_cycles_per_s = all_idle_bins ? std::accumulate(idle_active.begin(), idle_active.end(), 0.0) / (all_idle_bins * bin) : 0.0;
  // Only complete sweeps: the first and last groups may be cut by the ends of the run.
  double sum = 0;
  uint64_t spi_sum = 0;
  size_t worst = 0;
  for (size_t k = 1; k + 1 < sweeps.size(); ++k) {
    const auto& sw = sweeps[k];
    double a = 0;
    for (int i = sw.first; i <= sw.second; ++i) a += double(active[size_t(i)]), spi_sum += spi[size_t(i)];
    const size_t phase = tach_phase[size_t(sw.first)];
    const double idle_rate = idle_bins[phase] ? idle_active[phase] / (idle_bins[phase] * bin) : c.idle_cycles_per_s;
    const double cost = a - idle_rate * (sw.second - sw.first + 1) * bin;
    sum += cost;
    const bool speed_change = std::any_of(change_bins.begin(), change_bins.end(), [&](int b) {
      return b < sw.first && b > sweeps[k - 1].first;
    });
    if (speed_change) c.speed_change_max = std::max(c.speed_change_max, cost);
    if (std::getenv("BTSM_BENCH_VERBOSE"))
      std::printf("   sweep at %.3f s: %.0f cycles%s\n", start_s + sw.first * bin, cost, speed_change ? " (speed change)" : "");
    if (cost > c.sweep_cycles_max) c.sweep_cycles_max = cost, worst = k;
    ++c.sweeps;
  }
  if (profiling && worst) {
    // As the sweep figure: the sweep's bins minus each function's mean idle load over as many bins.
    const size_t phase = tach_phase[size_t(sweeps[worst].first)];
    std::map<uint32_t, double> net;
    for (int i = 0; i < bins; ++i) {
      if (i < first_spi) continue;
      if (in_sweep[size_t(i)] && (i < sweeps[worst].first || i > sweeps[worst].second)) continue;
      if (!in_sweep[size_t(i)] && tach_phase[size_t(i)] != phase) continue;
      const double w = in_sweep[size_t(i)] ? 1.0 : -double(sweeps[worst].second - sweeps[worst].first + 1) / idle_bins[phase];
      for (const auto& [sym, cycles] : bin_profiles[size_t(i)]) net[sym] += w * double(cycles);
    }
    for (const auto& [sym, cycles] : net) c.worst_profile.push_back({symbols.names[sym], cycles});
    std::sort(c.worst_profile.begin(), c.worst_profile.end(), [](const auto& x, const auto& y) { return x.second > y.second; });
  }
  if (c.sweeps) {
    c.sweep_cycles = sum / c.sweeps;
    c.spi_bytes_per_sweep = spi_sum / uint64_t(c.sweeps);
  }
  if (std::getenv("BTSM_BENCH_VERBOSE"))
    for (const auto& sw : sweeps) std::printf("   sweep %.3f .. %.3f s\n", start_s + sw.first * bin, start_s + sw.second * bin);
  if (sweeps.size() >= 3) c.period_s = (sweeps[sweeps.size() - 2].first - sweeps[1].first) * bin / double(sweeps.size() - 3);
  return c;
}

const double kProbeTempsC[5] = {33.5, 32.1, 30.7, 20.0, 26.0};

// Without a model: the image as flashed, fixed probe resistances, tach at 100 Hz (6000 rpm).
CycleFigures measure_cycles(const std::string& elf, double seconds) {
  btsm::sim::Ad7794Model adc;
  for (int i = 0; i < 5; ++i) adc.front_end().probe_ohm[size_t(i)] = btsm::sim::pt1000_ohm(kProbeTempsC[i]);
  btsm::sim::SpiModelAdapter<btsm::sim::Ad7794Model> bus(adc);
  btsm::sim::HarnessOptions o;
  o.elf_path = elf;
  btsm::sim::SimavrHarness h(o, &bus);
  h.set_tach_hz(100.0);
  return measure_cycles(h, elf, 2.0, seconds);  // boot and calibration are not part of the figure
}

// The production configuration: the same, with a reduced model uploaded (authenticated, over the
// UART) and running, so every sweep also steps the model and checks the model's limits. The
// spindle changes speed three times, 6000 -> 5400 -> 6600 -> 6000 rpm, between sweeps: the test
// model's breakpoints are 0 and 6000 rpm, so 5400 rpm needs both breakpoints read and
// interpolated (the costliest refresh), 6600 rpm holds the top one and 6000 rpm is on it.
// `after_reboot` (optional): the same module power-cycled with the model stored, at 6000 rpm, and
// the speed moved to 5400 rpm (interpolated) before the second sweep -- the first update of the
// Kalman filters after their initialisation and the first model step at a new speed in one sweep.
// The first sweep after start-up (with the calibration before it, every channel's open-wire check
// and the model's start) is one SPI group with the calibration and is left out, as in every
// measurement here.
CycleFigures measure_cycles_with_model(const std::string& elf, double seconds, int ram_bytes,
                                       CycleFigures* after_reboot = nullptr) {
  setenv("BTSM_FW_ELF", elf.c_str(), 1);  // btsm::test::firmware_elf()
  btsm::test::AvrLink l;
  for (int i = 0; i < 5; ++i) l.adc.front_end().probe_ohm[size_t(i)] = btsm::sim::pt1000_ohm(kProbeTempsC[i]);
  l.h->set_tach_hz(100.0);
  l.step(0.5);
  // Stack depth under real load (AD7794 attached, authenticated upload, model start-up, sweeps
  // with the model, interrupts): paint the free SRAM below the current stack pointer, scan after.
  avr_t* core = l.h->core();
  const int bss_end = 0x100 + ram_bytes;
  btsm::bench::paint_sram(core, bss_end, btsm::bench::stack_pointer(core) - 1);
  uint8_t seq = 0;
  if (btsm::test::upload_model(l, btsm::test::spindle_model_blob(0), seq) != 0) {
    std::printf("   model upload failed\n");
    return CycleFigures();
  }
  if (std::getenv("BTSM_BENCH_VERBOSE")) std::printf("   model committed at %.3f s\n", l.h->time_s());
  const std::vector<TachChange> changes = {{11.0, 90.0}, {21.0, 110.0}, {31.0, 100.0}};
  CycleFigures c = measure_cycles(*l.h, elf, std::max(2.0, l.h->time_s() + 0.5), seconds, changes);
  if (std::getenv("BTSM_BENCH_VERBOSE")) {
    l.step(0.0);
    for (const auto& smp : l.capture().samples) std::printf("   sample t %.3f s speed %u rpm\n", smp.time_ms * 1e-3, smp.speed_rpm);
  }
  const btsm::bench::StackDepth depth = btsm::bench::stack_depth(core, bss_end);
  c.stack_max = depth.max_use;
  c.stack_margin = depth.margin;
  if (after_reboot) {
    l.h->set_tach_hz(100.0);
    l.reboot();
    *after_reboot = measure_cycles(*l.h, elf, l.h->time_s(), 32.0, {{4.0, 90.0}});
  }
  return c;
}

void print_cycles(const CycleFigures& c) {
  std::printf("   active cycles per 5-channel sample cycle (idle tick load removed): mean %.0f, max %.0f"
              " (target <= 40000 for every sweep: %s)\n", c.sweep_cycles, c.sweep_cycles_max, c.sweep_cycles_max <= 40000 ? "met" : "NOT met");
  std::printf("   SPI bytes per sweep: %llu\n", (unsigned long long)c.spi_bytes_per_sweep);
  std::printf("   idle load outside sweeps: %.0f cycles/s (%.2f %% of the CPU)\n", c.idle_cycles_per_s,
              100.0 * c.idle_cycles_per_s / 16e6);
  if (c.period_s > 0) {
    const double sweep_duty = c.sweep_cycles / (c.period_s * 16e6);
    std::printf("   sample period %.2f s: sweep duty %.4f %%, with the idle load %.3f %% (target < 1 %%: %s)\n",
                c.period_s, 100.0 * sweep_duty, 100.0 * (sweep_duty + c.idle_cycles_per_s / 16e6),
                sweep_duty + c.idle_cycles_per_s / 16e6 < 0.01 ? "met" : "NOT met");
  }
  if (c.speed_change_max >= 0)
    std::printf("   sweeps that see a new tach speed: max %.0f cycles (included in the max above)\n", c.speed_change_max);
  if (!c.worst_profile.empty()) {
    std::printf("   profile of the worst sweep (active cycles by function, idle tick load removed):\n");
    const int top = std::max(15, std::atoi(std::getenv("BTSM_BENCH_PROFILE")));
    for (size_t k = 0; k < c.worst_profile.size() && k < size_t(top); ++k)
      std::printf("   %8.0f  %s\n", c.worst_profile[k].second, c.worst_profile[k].first.c_str());
  }
  if (c.stack_max >= 0)
    std::printf("   deepest stack (upload, model start-up, sweeps, interrupts): %d B, never touched %d B"
                " (target >= 64: %s)\n", c.stack_max, c.stack_margin, c.stack_margin >= 64 ? "met" : "NOT met");
}

double speedup(btsm::sim::BoardKind kind, const std::string& elf, double sim_s) {
  btsm::sim::SimModuleOptions o;
  o.board = kind;
  o.elf_path = elf;
  o.plant.speed = btsm::sim::SpeedProfile::parse("30m@6000,30m@0");
  btsm::sim::SimModule m(o);
  const auto t0 = std::chrono::steady_clock::now();
  double done = 0;
  while (done < sim_s) {
    m.run_for(10.0);
    m.host_receive();
    done += 10.0;
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return done / wall;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string elf = argc > 1 ? argv[1] : std::string(BTSM_BIN_DIR) + "/btsm-fw-bluno.elf";
  std::printf("== firmware bench (image %s)\n", elf.c_str());
  if (!std::filesystem::exists(elf)) {
    std::printf("image missing: only the native speed-up is measured\n");
  } else {
    const auto s = elf_sections(elf);
    std::printf("-- memory (ELF sections)\n");
    for (const auto& [name, size] : s.by_name) std::printf("   %-12s %6llu B\n", name.c_str(), (unsigned long long)size);
    std::printf("   flash (text + data + other program-memory sections): %llu B of 30720 B budget (%.1f %%) %s\n",
                (unsigned long long)s.flash, 100.0 * double(s.flash) / 30720.0, s.flash <= 30720 ? "OK" : "OVER BUDGET");
    std::printf("   RAM (data + bss): %llu B of 1536 B budget (%.1f %%) %s\n", (unsigned long long)s.ram,
                100.0 * double(s.ram) / 1536.0, s.ram <= 1536 ? "OK" : "OVER BUDGET");

    const auto c = measure_cycles(elf, 42.0);
    std::printf("-- CPU (simavr, 16 MHz, SPI at fosc/4, %d sweeps, no model)\n", c.sweeps);
    print_cycles(c);
    CycleFigures r;
    const auto m = measure_cycles_with_model(elf, 42.0, int(s.ram), &r);
    std::printf("-- CPU with a reduced model active (%d sweeps; model step and limit checks included)\n", m.sweeps);
    print_cycles(m);
    std::printf("-- CPU after a power cycle with the model stored (%d sweeps; speed change before the first filter "
                "update)\n", r.sweeps);
    print_cycles(r);
  }
  std::printf("-- simulated-time speed-up (sim s per wall s, 1 h profile, plant + AD7794 + firmware)\n");
  const double native = speedup(btsm::sim::BoardKind::Native, elf, 3600.0);
  std::printf("   native board: %.0fx\n", native);
  if (std::filesystem::exists(elf)) {
    const double avr = speedup(btsm::sim::BoardKind::Avr, elf, 300.0);
    std::printf("   avr board (simavr): %.0fx (native / avr = %.0f)\n", avr, native / avr);
  }
  return 0;
}
