// Native simulated board; see the header.
#include "boards/sim/native_board.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "common/device_key.hpp"
#include "hal/contracts.hpp"

namespace btsm::sim {

static_assert(btsm::hal::CheckBoard<NativeBoard>::value, "NativeBoard must satisfy the HAL contract");

namespace {
constexpr uint64_t kNoEvent = std::numeric_limits<uint64_t>::max();
constexpr double kTachTickUs = 4.0;  // AVR board: Timer1 at 16 MHz / 64
}  // namespace

NativeBoard::NativeBoard(const NativeBoardOptions& options)
    : opt_(options), adc_(options.adc), eeprom_(kEepromSize, 0xFF) {
  key_record_.fill(0xFF);
  if (!opt_.erased_key) {
    std::array<uint8_t, 32> key{};
    if (opt_.key) {
      key = *opt_.key;
    } else {
      for (uint8_t i = 0; i < 32; ++i) key[i] = device_key::dev_key_byte(i);
    }
    device_key::build_record(key_record_.data(), opt_.device_id, key.data());
  }
  entropy_state_ = opt_.entropy_seed;
}

uint64_t NativeBoard::byte_time_us() const {
  return opt_.uart_baud == 0 ? 0 : (10ULL * 1000000ULL + opt_.uart_baud - 1) / opt_.uart_baud;
}

// ---- serial ---------------------------------------------------------------------------------

bool NativeBoard::Serial::read(uint8_t& byte) {
  if (b->rx_ring_.empty()) return false;
  byte = b->rx_ring_.front();
  b->rx_ring_.pop_front();
  return true;
}

// The AVR ring hands out its free space in up to two contiguous pieces; a staging buffer of the
// whole free space models the contract (the encoder must not assume more than one claim is
// needed, and it gets at most the ring's free space).
uint8_t* NativeBoard::Serial::tx_claim(uint8_t& n) {
  const size_t free = b->opt_.tx_buffer_bytes - b->tx_ring_.size();
  n = static_cast<uint8_t>(free > 255 ? 255 : free);
  b->tx_claimed_.assign(n, 0xA5);  // garbage where nothing was written
  return b->tx_claimed_.data();
}

void NativeBoard::Serial::tx_commit(uint8_t n) {
  if (n > b->tx_claimed_.size()) throw std::logic_error("tx_commit: more bytes than claimed");
  if (n == 0) return;
  if (b->tx_ring_.empty() && b->next_tx_us_ < b->now_us_) b->next_tx_us_ = b->now_us_;
  b->tx_ring_.insert(b->tx_ring_.end(), b->tx_claimed_.begin(), b->tx_claimed_.begin() + n);
  b->tx_claimed_.clear();
  if (b->byte_time_us() == 0) b->advance_us(0);
}

void NativeBoard::host_send(const uint8_t* data, size_t n) {
  if (rx_wire_.empty() && next_rx_us_ < now_us_) next_rx_us_ = now_us_;
  rx_wire_.insert(rx_wire_.end(), data, data + n);
  if (byte_time_us() == 0) advance_us(0);
}

std::vector<uint8_t> NativeBoard::host_receive() {
  std::vector<uint8_t> out;
  out.swap(tx_done_);
  return out;
}

// ---- storage --------------------------------------------------------------------------------

void NativeBoard::Storage::write(uint16_t addr, uint8_t value) {
  if (!b->powered_) return;
  const uint64_t index = b->eeprom_writes_++;
  if (b->cut_at_write_ && index >= *b->cut_at_write_) {
    b->eeprom_[addr % kEepromSize] = b->torn_value_;
    b->powered_ = false;
    b->reset_pending_ = ResetCause::kPowerLoss;
    return;
  }
  b->eeprom_[addr % kEepromSize] = value;
  b->eeprom_busy_until_us_ = b->now_us_ + b->opt_.eeprom_write_us;
}

void NativeBoard::cut_power_at_write(uint64_t write_index, uint8_t torn_value) {
  cut_at_write_ = eeprom_writes_ + write_index;
  torn_value_ = torn_value;
}

// ---- watchdog, reset ------------------------------------------------------------------------

void NativeBoard::Watchdog::enable() {
  b->watchdog_enabled_ = true;
  b->last_kick_us_ = b->now_us_;
}

void NativeBoard::mcu_reset() {
  last_reset_by_watchdog_ = reset_pending_ == ResetCause::kWatchdog;
  first_boot_ = reset_pending_ == ResetCause::kPowerLoss;
  if (reset_pending_ == ResetCause::kPowerLoss) adc_.power_on_reset();
  reset_pending_ = ResetCause::kNone;
  powered_ = true;
  cut_at_write_.reset();
  watchdog_enabled_ = false;
  rx_ring_.clear();
  tx_ring_.clear();
  eeprom_busy_until_us_ = now_us_;
  adc_.set_cs(false);
}

// ---- tach, identity -------------------------------------------------------------------------

uint16_t NativeBoard::Tach::rpm() {
  const double rpm = b->spindle_rpm_;
  if (rpm <= 0.0) return 0;
  // Period measurement between pulses with 4 us ticks, as on the AVR board; no pulse for 2 s
  // means stopped.
  const double period_us = 60e6 / (rpm * b->pulses_per_rev_);
  if (period_us > 2e6) return 0;
  const double ticks = std::max(1.0, std::round(period_us / kTachTickUs));
  const double measured = 60e6 / (ticks * kTachTickUs * b->pulses_per_rev_);
  return static_cast<uint16_t>(std::min(65534.0, std::round(measured)));
}

void NativeBoard::Identity::read_key_record(uint8_t* out, uint16_t n) {
  for (uint16_t i = 0; i < n && i < b->key_record_.size(); ++i) out[i] = b->key_record_[i];
}

uint16_t NativeBoard::Identity::entropy_bits() {
  uint64_t z = (b->entropy_state_ += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return static_cast<uint16_t>(z ^ (z >> 31));
}

// ---- time -----------------------------------------------------------------------------------

void NativeBoard::sync_adc() {
  const double target_s = static_cast<double>(now_us_) * 1e-6;
  if (target_s > adc_.now()) adc_.advance(target_s - adc_.now());
}

uint64_t NativeBoard::us_to_next_event() const {
  uint64_t next = kNoEvent;
  const double adc_s = adc_.time_to_next_event();
  if (adc_s != Ad7794Model::kNever) {
    // Round up so the conversion has completed when we get there.
    const double target_s = adc_.now() + adc_s;
    const auto target_us = static_cast<uint64_t>(std::ceil(target_s * 1e6 - 1e-6));
    next = std::min(next, target_us > now_us_ ? target_us - now_us_ : 0);
  }
  // A UART byte completes one byte time after it started.
  const uint64_t byte_us = byte_time_us();
  if (!rx_wire_.empty()) {
    const uint64_t done = next_rx_us_ + byte_us;
    next = std::min(next, done > now_us_ ? done - now_us_ : 0);
  }
  if (!tx_ring_.empty()) {
    const uint64_t done = next_tx_us_ + byte_us;
    next = std::min(next, done > now_us_ ? done - now_us_ : 0);
  }
  if (eeprom_busy_until_us_ > now_us_) next = std::min(next, eeprom_busy_until_us_ - now_us_);
  if (watchdog_enabled_) {
    const uint64_t deadline = last_kick_us_ + uint64_t(opt_.watchdog_timeout_ms) * 1000;
    next = std::min(next, deadline > now_us_ ? deadline - now_us_ : 0);
  }
  return next;
}

void NativeBoard::advance_us(uint64_t dt_us) {
  const uint64_t t_end = now_us_ + dt_us;
  const uint64_t byte_us = byte_time_us();
  {
    // UART receive: one byte per byte time lands in the ring (or overruns it).
    while (!rx_wire_.empty() && next_rx_us_ + byte_us <= t_end) {
      next_rx_us_ += byte_us;
      if (rx_ring_.size() < opt_.rx_buffer_bytes) {
        rx_ring_.push_back(rx_wire_.front());
      } else {
        ++rx_overruns_;
      }
      rx_wire_.pop_front();
    }
    // UART transmit.
    while (!tx_ring_.empty() && next_tx_us_ + byte_us <= t_end) {
      next_tx_us_ += byte_us;
      tx_done_.push_back(tx_ring_.front());
      tx_ring_.pop_front();
    }
  }
  now_us_ = t_end;
  sync_adc();
  if (watchdog_enabled_ && reset_pending_ == ResetCause::kNone &&
      now_us_ - last_kick_us_ >= uint64_t(opt_.watchdog_timeout_ms) * 1000) {
    reset_pending_ = ResetCause::kWatchdog;
    ++watchdog_resets_;
  }
}

void NativeBoard::advance_to_next_event(uint64_t max_us) {
  uint64_t step = std::min(us_to_next_event(), max_us);
  if (step == 0) step = 1;
  advance_us(step);
}

}  // namespace btsm::sim
