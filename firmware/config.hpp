// Module configuration (SET_CONFIG / GET_CONFIG keys of common/wire_messages.hpp), its defaults,
// and its EEPROM record (firmware/eeprom_layout.hpp: magic, version, length, payload, CRC-16).
#ifndef BTSM_FIRMWARE_CONFIG_HPP
#define BTSM_FIRMWARE_CONFIG_HPP

#include <stdint.h>

#include "common/byte_order.hpp"
#include "common/crc.hpp"
#include "common/wire_messages.hpp"
#include "firmware/eeprom_layout.hpp"

namespace btsm {

struct FirmwareConfig {
  uint32_t sample_period_ms;     // ms between sweeps
  uint32_t r_ref_milliohm;       // reference resistor, mOhm
  uint32_t kalman_q;             // (mK)^2 per second
  uint32_t kalman_r;             // (mK)^2
  uint8_t tach_pulses_per_rev;   // 1..64
  uint8_t adc_fs;                // AD7794 FS code 1..15
  uint8_t alarm_latch;           // 0/1
  uint8_t roles[wire::kChannels];  // wire::ChannelRole

  // Value of a key (false for unknown keys).
  bool get(uint8_t key, int32_t& value) const {
    if (key >= wire::kChannelRoleKeyFirst && key <= wire::kChannelRoleKeyLast) {
      value = roles[key - wire::kChannelRoleKeyFirst];
      return true;
    }
    switch (static_cast<wire::ConfigKey>(key)) {
      case wire::ConfigKey::SamplePeriodMs: value = static_cast<int32_t>(sample_period_ms); return true;
      case wire::ConfigKey::TachPulsesPerRev: value = tach_pulses_per_rev; return true;
      case wire::ConfigKey::RrefMilliohm: value = static_cast<int32_t>(r_ref_milliohm); return true;
      case wire::ConfigKey::AdcUpdateRateCode: value = adc_fs; return true;
      case wire::ConfigKey::KalmanProcessNoise: value = static_cast<int32_t>(kalman_q); return true;
      case wire::ConfigKey::KalmanMeasurementNoise: value = static_cast<int32_t>(kalman_r); return true;
      case wire::ConfigKey::AlarmLatch: value = alarm_latch; return true;
      default: return false;
    }
  }

  // Sets a key after range checking (false: unknown key or value out of range, nothing changed).
  bool set(uint8_t key, int32_t value) {
    if (!wire::config_value_valid(key, value)) return false;
    if (key >= wire::kChannelRoleKeyFirst && key <= wire::kChannelRoleKeyLast) {
      roles[key - wire::kChannelRoleKeyFirst] = static_cast<uint8_t>(value);
      return true;
    }
    switch (static_cast<wire::ConfigKey>(key)) {
      case wire::ConfigKey::SamplePeriodMs: sample_period_ms = static_cast<uint32_t>(value); return true;
      case wire::ConfigKey::TachPulsesPerRev: tach_pulses_per_rev = static_cast<uint8_t>(value); return true;
      case wire::ConfigKey::RrefMilliohm: r_ref_milliohm = static_cast<uint32_t>(value); return true;
      case wire::ConfigKey::AdcUpdateRateCode: adc_fs = static_cast<uint8_t>(value); return true;
      case wire::ConfigKey::KalmanProcessNoise: kalman_q = static_cast<uint32_t>(value); return true;
      case wire::ConfigKey::KalmanMeasurementNoise: kalman_r = static_cast<uint32_t>(value); return true;
      case wire::ConfigKey::AlarmLatch: alarm_latch = static_cast<uint8_t>(value); return true;
      default: return false;
    }
  }

  void set_defaults() {
    // Every key 0x01..0x14 that config_key_range() knows (no key table: it would sit in SRAM).
    wire::ConfigRange r;
    for (uint8_t key = 0x01; key <= wire::kChannelRoleKeyLast; ++key) {
      if (wire::config_key_range(key, r)) set(key, r.default_value);
    }
  }

  // Bit j set when channel j is measured (role not Disabled).
  uint8_t enabled_mask() const {
    uint8_t m = 0;
    for (uint8_t j = 0; j < wire::kChannels; ++j)
      if (roles[j] != static_cast<uint8_t>(wire::ChannelRole::Disabled)) m = static_cast<uint8_t>(m | (1u << j));
    return m;
  }
};

namespace config_record {
static constexpr uint8_t kMagic = 0xC5;
static constexpr uint8_t kVersion = 1;
static constexpr uint8_t kPayload = 4 * 4 + 3 + wire::kChannels;  // 24
static constexpr uint8_t kSize = 3 + kPayload + 2;
static_assert(kSize <= eeprom_layout::kConfigSize, "config record exceeds its EEPROM area");

inline void encode(const FirmwareConfig& c, uint8_t* out /* kSize */) {
  out[0] = kMagic;
  out[1] = kVersion;
  out[2] = kPayload;
  uint8_t* p = out + 3;
  put_le32(p, c.sample_period_ms);
  put_le32(p + 4, c.r_ref_milliohm);
  put_le32(p + 8, c.kalman_q);
  put_le32(p + 12, c.kalman_r);
  p[16] = c.tach_pulses_per_rev;
  p[17] = c.adc_fs;
  p[18] = c.alarm_latch;
  for (uint8_t j = 0; j < wire::kChannels; ++j) p[19 + j] = c.roles[j];
  put_le16(out + 3 + kPayload, crc16_ccitt(out, 3 + kPayload));
}

// False (and `c` untouched) when the record is missing, corrupt or holds an out-of-range value.
inline bool decode(const uint8_t* in, FirmwareConfig& c) {
  if (in[0] != kMagic || in[1] != kVersion || in[2] != kPayload) return false;
  if (crc16_ccitt(in, 3 + kPayload) != get_le16(in + 3 + kPayload)) return false;
  const uint8_t* p = in + 3;
  FirmwareConfig t;
  t.set_defaults();
  bool ok = t.set(0x01, static_cast<int32_t>(get_le32(p))) && t.set(0x03, static_cast<int32_t>(get_le32(p + 4))) &&
            t.set(0x05, static_cast<int32_t>(get_le32(p + 8))) && t.set(0x06, static_cast<int32_t>(get_le32(p + 12))) &&
            t.set(0x02, p[16]) && t.set(0x04, p[17]) && t.set(0x07, p[18]);
  for (uint8_t j = 0; j < wire::kChannels && ok; ++j) ok = t.set(wire::channel_role_key(j), p[19 + j]);
  if (ok) c = t;
  return ok;
}
}  // namespace config_record

}  // namespace btsm

#endif
