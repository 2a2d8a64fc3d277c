// BTSM wire messages: type codes, payload structs and checked codec pairs.
//
// Every message has `uint8_t encode_X(const X&, uint8_t* payload)` returning the payload length
// (0 if the struct holds a value the protocol cannot carry — callers treat 0 as a bug) and
// `bool decode_X(const uint8_t* payload, uint8_t len, X&)` which rejects a wrong length or an
// out-of-range value and leaves `out` unspecified on failure. All fields are little-endian
// (byte_order.hpp). Decoding is strict, so decode followed by encode reproduces the payload
// bytes exactly. `payload` buffers must hold kMaxPayload (58) bytes; every payload fits.
//
// Direction: types 0x01..0x3F module -> host, 0x40..0x7F host -> module.
// Sequence numbers: the host numbers its requests; the module echoes `seq` and `type` in ACK.
// The module numbers its own SAMPLE stream so the host can detect dropped samples.
#ifndef BTSM_COMMON_WIRE_MESSAGES_HPP
#define BTSM_COMMON_WIRE_MESSAGES_HPP

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "byte_order.hpp"
#include "channels.hpp"
#include "wire_frame.hpp"

namespace btsm {
namespace wire {

// ---------------------------------------------------------------------------------------------
// Message types.
enum class MsgType : uint8_t {
  // module -> host
  Sample = 0x01,
  Info = 0x02,
  Ack = 0x03,
  AuthChallenge = 0x04,
  ModelData = 0x05,
  Config = 0x06,  // answer to GET_CONFIG (extension of the contract's list)
  // host -> module
  GetInfo = 0x40,
  SetSpeed = 0x41,
  SetConfig = 0x42,
  AckAlarm = 0x43,
  ModelBegin = 0x44,
  ModelChunk = 0x45,
  ModelCommit = 0x46,
  ModelRead = 0x47,
  Reboot = 0x48,
  GetConfig = 0x49,  // extension: read one configuration value back
  ModelAuth = 0x4A,  // proves the device key before the module writes any byte of an upload
};

inline uint8_t type_code(MsgType t) { return static_cast<uint8_t>(t); }

inline bool is_host_to_module(uint8_t type) { return type >= 0x40 && type <= 0x7F; }

// Upper-case protocol name of a type ("SAMPLE"), or nullptr for an unknown code.
inline const char* msg_type_name(uint8_t type) {
  switch (static_cast<MsgType>(type)) {
    case MsgType::Sample: return "SAMPLE";
    case MsgType::Info: return "INFO";
    case MsgType::Ack: return "ACK";
    case MsgType::AuthChallenge: return "AUTH_CHALLENGE";
    case MsgType::ModelData: return "MODEL_DATA";
    case MsgType::Config: return "CONFIG";
    case MsgType::GetInfo: return "GET_INFO";
    case MsgType::SetSpeed: return "SET_SPEED";
    case MsgType::SetConfig: return "SET_CONFIG";
    case MsgType::AckAlarm: return "ACK_ALARM";
    case MsgType::ModelBegin: return "MODEL_BEGIN";
    case MsgType::ModelChunk: return "MODEL_CHUNK";
    case MsgType::ModelCommit: return "MODEL_COMMIT";
    case MsgType::ModelRead: return "MODEL_READ";
    case MsgType::Reboot: return "REBOOT";
    case MsgType::GetConfig: return "GET_CONFIG";
    case MsgType::ModelAuth: return "MODEL_AUTH";
  }
  return nullptr;
}

// ---------------------------------------------------------------------------------------------
// ACK status / NACK codes. 0 = OK; anything else is the reason a request was refused.
enum class Nack : uint8_t {
  Ok = 0,
  UnknownType = 1,   // message type not handled by this firmware
  BadLength = 2,     // payload length wrong for the type (decode_X failed on length)
  NoSession = 3,     // MODEL_AUTH without MODEL_BEGIN, MODEL_CHUNK/COMMIT without an accepted
                     // MODEL_AUTH (or after a failed one)
  BadOffset = 4,     // chunk/read offset not where expected or beyond the blob
  AuthFailed = 5,    // HMAC tag (MODEL_AUTH or MODEL_COMMIT) wrong, or no device key
  BlobCrc = 6,       // CRC-32 of received blob != MODEL_BEGIN's (or blob-internal CRC)
  BlobVersion = 7,   // blob magic/version not understood by this firmware
  BlobInvalid = 8,   // NaN, unstable pole, out-of-range gains
  StoreFailed = 9,   // EEPROM write/verify failed
  BadValue = 10,     // field value out of range (e.g. SET_CONFIG key/value)
  Busy = 11,         // cannot do it now (e.g. model update while committing)
};
const uint8_t kNackCodeCount = 12;  // codes 0..11

// Upper-case code name ("AUTH_FAILED"); "UNKNOWN_NACK" for codes this version does not know.
inline const char* nack_name(uint8_t code) {
  switch (static_cast<Nack>(code)) {
    case Nack::Ok: return "OK";
    case Nack::UnknownType: return "UNKNOWN_TYPE";
    case Nack::BadLength: return "BAD_LENGTH";
    case Nack::NoSession: return "NO_SESSION";
    case Nack::BadOffset: return "BAD_OFFSET";
    case Nack::AuthFailed: return "AUTH_FAILED";
    case Nack::BlobCrc: return "BLOB_CRC";
    case Nack::BlobVersion: return "BLOB_VERSION";
    case Nack::BlobInvalid: return "BLOB_INVALID";
    case Nack::StoreFailed: return "STORE_FAILED";
    case Nack::BadValue: return "BAD_VALUE";
    case Nack::Busy: return "BUSY";
  }
  return "UNKNOWN_NACK";
}

// One-line explanation for host error messages.
inline const char* nack_description(uint8_t code) {
  switch (static_cast<Nack>(code)) {
    case Nack::Ok: return "accepted";
    case Nack::UnknownType: return "the module does not know this message type";
    case Nack::BadLength: return "payload length is wrong for this message type";
    case Nack::NoSession: return "no authenticated model upload in progress (MODEL_BEGIN and MODEL_AUTH first)";
    case Nack::BadOffset: return "offset is not the next expected one or lies beyond the blob";
    case Nack::AuthFailed: return "HMAC check failed (wrong device key or stale nonce)";
    case Nack::BlobCrc: return "model blob CRC-32 mismatch";
    case Nack::BlobVersion: return "model blob version not supported by this firmware";
    case Nack::BlobInvalid: return "model blob rejected (NaN, unstable pole or gain out of range)";
    case Nack::StoreFailed: return "EEPROM write or verify failed";
    case Nack::BadValue: return "a field value is out of range";
    case Nack::Busy: return "module busy, retry later";
  }
  return "unknown NACK code (newer firmware?)";
}

// ---------------------------------------------------------------------------------------------
// Common constants.
using ::btsm::kChannels;  // common/channels.hpp
const int32_t kMissing = -8388608L;  // i24 temperature placeholder: fault, disabled or no model
const uint16_t kSpeedFromTach = 0xFFFF;  // SET_SPEED value: measure speed with the tach input
const uint16_t kMaxSpeedRpm = 60000;     // highest explicit SET_SPEED value
const uint16_t kMaxModelBlobSize = 464;  // contract bound on kReducedModelBlobSize
const uint8_t kNonceSize = 16;
const uint8_t kHmacSize = 32;
const uint8_t kMaxModelData = kMaxPayload - 2;  // 56 data bytes after the u16 offset

// Diagnosis state, low two bits of SAMPLE channel_status and overall.
enum class DiagState : uint8_t { Normal = 0, Warn = 1, Alarm = 2, SensorFault = 3 };

inline const char* diag_state_name(uint8_t s) {
  switch (s & 0x03u) {
    case 0: return "NORMAL";
    case 1: return "WARN";
    case 2: return "ALARM";
    default: return "SENSOR_FAULT";
  }
}

// SAMPLE channel_status = DiagState | fault bits (any combination is legal).
const uint8_t kStatusStateMask = 0x03;
const uint8_t kFaultOpen = 0x04;         // over-range / open probe or wire
const uint8_t kFaultShort = 0x08;        // under-range / shorted probe
const uint8_t kFaultAdc = 0x10;          // ADC timeout, ERR bit or missing chip
const uint8_t kFaultReference = 0x20;    // reference lost (NOXREF)
const uint8_t kFaultKalmanReject = 0x40; // last reading rejected as an outlier by the filter
const uint8_t kStatusDisabled = 0x80;    // channel role is Disabled (temp is kMissing)

// SAMPLE overall = worst DiagState | flags; bits 5..7 are reserved and must be 0.
const uint8_t kOverallAlarmLatched = 0x04;  // an ALARM is latched (until ACK_ALARM or M normal samples)
const uint8_t kOverallModelActive = 0x08;   // a valid reduced model is predicting
const uint8_t kOverallSpeedFromTach = 0x10; // speed_rpm measured by tach (else host-set)
const uint8_t kOverallReservedMask = 0xE0;

// ---------------------------------------------------------------------------------------------
// Configuration keys for SET_CONFIG / GET_CONFIG (i32 value, unit per key).
enum class ConfigKey : uint8_t {
  SamplePeriodMs = 0x01,      // ms between sweeps of all channels; [1000, 600000], default 5000
  TachPulsesPerRev = 0x02,    // tach pulses per spindle revolution; [1, 64], default 1
  RrefMilliohm = 0x03,        // reference resistor, mOhm; [1000000, 20000000], default 6800000
  AdcUpdateRateCode = 0x04,   // AD7794 FS code; [1, 15], default 10 (16.7 Hz, 50/60 Hz reject)
  KalmanProcessNoise = 0x05,  // Kalman q, (mK)^2 per second of sample period; [1, 100000000],
                              // default 400 (20 mK/sqrt(s) random walk). 0 is out of range (NACK
                              // BadValue): a filter without process noise cannot follow anything
  KalmanMeasurementNoise = 0x06,  // Kalman r, (mK)^2; [1, 100000000], default 2500 (50 mK rms)
  AlarmLatch = 0x07,          // 1 = ALARM stays until ACK_ALARM, 0 = clears after 60 normal samples (diagnosis_stage.hpp); default 1
  ChannelRole0 = 0x10,        // ChannelRole of channel 1 (keys 0x10..0x14 = channels 1..5)
};
const uint8_t kChannelRoleKeyFirst = 0x10;
const uint8_t kChannelRoleKeyLast = kChannelRoleKeyFirst + kChannels - 1;

inline uint8_t channel_role_key(uint8_t channel_index) {
  return static_cast<uint8_t>(kChannelRoleKeyFirst + channel_index);
}

// What a probe measures. Predictions are relative to the Ambient channel.
enum class ChannelRole : uint8_t {
  Disabled = 0,
  Ambient = 1,
  FrontBearing = 2,
  RearBearing = 3,
  Housing = 4,
  Motor = 5,
  Coolant = 6,
  Spare = 7,  // measured and reported, no diagnosis limits
  Shaft = 8,  // probe on the (stationary) shaft end: the network's shaft node, diagnosed
};
const uint8_t kChannelRoleCount = 9;

inline const char* channel_role_name(uint8_t role) {
  switch (static_cast<ChannelRole>(role)) {
    case ChannelRole::Disabled: return "disabled";
    case ChannelRole::Ambient: return "ambient";
    case ChannelRole::FrontBearing: return "front_bearing";
    case ChannelRole::RearBearing: return "rear_bearing";
    case ChannelRole::Housing: return "housing";
    case ChannelRole::Motor: return "motor";
    case ChannelRole::Coolant: return "coolant";
    case ChannelRole::Spare: return "spare";
    case ChannelRole::Shaft: return "shaft";
  }
  return nullptr;
}

// Role byte of a role name ("rear_bearing" -> 3), or -1 when no role has that name: one lookup for
// every reader of role names (set-config values, recording metadata).
inline int channel_role_from_name(const char* name) {
  for (uint8_t r = 0; r < kChannelRoleCount; ++r) {
    const char* known = channel_role_name(r);
    if (known != nullptr && strcmp(name, known) == 0) return r;
  }
  return -1;
}

// A role that names a measured thermal point (a bearing, the housing, ...): it gets the model's
// limits in the module, and a network node of that name is what the channel measures. Disabled,
// ambient (the boundary) and spare channels are not.
inline bool is_thermal_role(uint8_t role) {
  return role != static_cast<uint8_t>(ChannelRole::Disabled) && role != static_cast<uint8_t>(ChannelRole::Ambient) &&
         role != static_cast<uint8_t>(ChannelRole::Spare);
}

// Contract default wiring: ch1 rear bearing, ch2 housing, ch3 front bearing, ch4 ambient, ch5 spare.
inline ChannelRole default_channel_role(uint8_t channel_index) {
  switch (channel_index) {
    case 0: return ChannelRole::RearBearing;
    case 1: return ChannelRole::Housing;
    case 2: return ChannelRole::FrontBearing;
    case 3: return ChannelRole::Ambient;
    default: return ChannelRole::Spare;
  }
}

struct ConfigRange {
  int32_t min;
  int32_t max;
  int32_t default_value;
};

namespace detail {
inline bool set_range(ConfigRange& r, int32_t min, int32_t max, int32_t default_value) {
  r.min = min;
  r.max = max;
  r.default_value = default_value;
  return true;
}
}  // namespace detail

// Valid range and default of a key; false for unknown keys. Per-channel role defaults follow
// default_channel_role(). (Field-wise assignment, not aggregate copies: on AVR those would put a
// constant table into .data, i.e. RAM.)
inline bool config_key_range(uint8_t key, ConfigRange& r) {
  if (key >= kChannelRoleKeyFirst && key <= kChannelRoleKeyLast) {
    return detail::set_range(
        r, 0, kChannelRoleCount - 1,
        static_cast<int32_t>(default_channel_role(static_cast<uint8_t>(key - kChannelRoleKeyFirst))));
  }
  switch (static_cast<ConfigKey>(key)) {
    case ConfigKey::SamplePeriodMs: return detail::set_range(r, 1000L, 600000L, 5000L);
    case ConfigKey::TachPulsesPerRev: return detail::set_range(r, 1L, 64L, 1L);
    case ConfigKey::RrefMilliohm: return detail::set_range(r, 1000000L, 20000000L, 6800000L);
    case ConfigKey::AdcUpdateRateCode: return detail::set_range(r, 1L, 15L, 10L);
    case ConfigKey::KalmanProcessNoise: return detail::set_range(r, 1L, 100000000L, 400L);
    case ConfigKey::KalmanMeasurementNoise: return detail::set_range(r, 1L, 100000000L, 2500L);
    case ConfigKey::AlarmLatch: return detail::set_range(r, 0L, 1L, 1L);
    case ConfigKey::ChannelRole0: break;  // handled above
  }
  return false;
}

inline bool config_value_valid(uint8_t key, int32_t value) {
  ConfigRange r;
  return config_key_range(key, r) && value >= r.min && value <= r.max;
}

// Lower-case key name for host messages ("sample_period_ms", "channel_role_3"); nullptr if
// unknown. Channel role names use 1-based channel numbers like the hardware labels.
inline const char* config_key_name(uint8_t key) {
  switch (key) {
    case 0x01: return "sample_period_ms";
    case 0x02: return "tach_pulses_per_rev";
    case 0x03: return "r_ref_milliohm";
    case 0x04: return "adc_update_rate_code";
    case 0x05: return "kalman_q_mk2_per_s";
    case 0x06: return "kalman_r_mk2";
    case 0x07: return "alarm_latch";
    case 0x10: return "channel_role_1";
    case 0x11: return "channel_role_2";
    case 0x12: return "channel_role_3";
    case 0x13: return "channel_role_4";
    case 0x14: return "channel_role_5";
    default: return nullptr;
  }
}

// ---------------------------------------------------------------------------------------------
// Message structs. Sizes are payload bytes.

// SAMPLE 0x01, 46 bytes: one sweep of all channels.
struct Sample {
  uint32_t sample_index;            // counts sweeps since reset
  uint32_t time_ms;                 // module uptime at the sweep, ms (wraps after 49.7 days)
  uint16_t speed_rpm;               // spindle speed used by the model, rpm
  int32_t temp_mK[kChannels];       // filtered temperature, mK (i24), kMissing if unavailable
  uint8_t channel_status[kChannels];  // DiagState | fault bits
  int32_t predicted_mK[kChannels];  // model prediction, mK (i24), kMissing if no model
  uint8_t overall;                  // worst DiagState | kOverall* flags
};
const uint8_t kSampleSize = 4 + 4 + 2 + 3 * kChannels + kChannels + 3 * kChannels + 1;

// INFO 0x02, 34 bytes: answer to GET_INFO.
struct Info {
  uint8_t fw_major, fw_minor, fw_patch;
  uint8_t protocol_version;  // kProtocolVersion of the firmware
  uint32_t device_id;        // unique per module (also selects the HMAC key on the host)
  uint32_t model_crc;        // CRC-32 of the active model blob, 0 if none
  uint32_t model_seq;        // increments with every committed model
  uint32_t uptime_s;
  uint8_t model_state;       // ModelState
  uint8_t reset_cause;       // MCUSR bits at boot (PORF 1, EXTRF 2, BORF 4, WDRF 8)
  uint16_t adc_timeouts;     // fault counters since reset, saturating at 65535 ...
  uint16_t frame_errors;
  uint16_t kalman_rejects;
  uint16_t sensor_faults;
  uint16_t resets;           // ... except these two, which persist in EEPROM
  uint16_t watchdog_resets;
};
const uint8_t kInfoSize = 4 + 4 * 4 + 2 + 6 * 2;

enum class ModelState : uint8_t {
  None = 0,      // nothing stored: no predictions
  Active = 1,    // valid blob loaded and predicting
  Rejected = 2,  // stored blob failed validation at boot (CRC/version/values)
};
const uint8_t kModelStateCount = 3;

// ACK 0x03, 5 bytes: answer to every host request except GET_INFO/MODEL_BEGIN/MODEL_READ/
// GET_CONFIG, which answer with data on success (and an ACK with a NACK code on failure).
struct Ack {
  uint8_t acked_seq;
  uint8_t acked_type;
  uint8_t status;   // Nack code, 0 = OK
  uint16_t detail;  // code-specific: expected offset for BAD_OFFSET, expected length for
                    // BAD_LENGTH, config key for BAD_VALUE, else 0
};
const uint8_t kAckSize = 5;

// AUTH_CHALLENGE 0x04, 16 bytes: fresh single-use nonce after MODEL_BEGIN.
struct AuthChallenge {
  uint8_t nonce[kNonceSize];
};

// MODEL_DATA 0x05 (module -> host) and MODEL_CHUNK 0x45 (host -> module), 3..58 bytes:
// u16 offset, then 1..56 blob bytes.
struct ModelBytes {
  uint16_t offset;  // byte offset into the blob
  uint8_t len;      // 1..kMaxModelData
  uint8_t data[kMaxModelData];
};
typedef ModelBytes ModelData;
typedef ModelBytes ModelChunk;

// CONFIG 0x06 and SET_CONFIG 0x42, 5 bytes.
struct ConfigValue {
  uint8_t key;    // ConfigKey (or channel_role_key(i))
  int32_t value;  // unit per key, see ConfigKey
};
const uint8_t kConfigValueSize = 5;

// SET_SPEED 0x41, 2 bytes.
struct SetSpeed {
  uint16_t rpm;  // 0..kMaxSpeedRpm, or kSpeedFromTach
};

// MODEL_BEGIN 0x44, 6 bytes.
struct ModelBegin {
  uint16_t total_len;   // blob size, 1..kMaxModelBlobSize
  uint32_t blob_crc32;  // crc32() of the whole blob
};

// MODEL_COMMIT 0x46, 32 bytes.
struct ModelCommit {
  uint8_t hmac[kHmacSize];  // HMAC-SHA256(device key, nonce || blob)
};

// MODEL_AUTH 0x4A, 32 bytes: sent after AUTH_CHALLENGE, before the first MODEL_CHUNK. The module
// writes no EEPROM byte of an upload until this tag checks out; a wrong tag ends the session.
//   hmac = HMAC-SHA256(device key, nonce || context), context = encode_model_auth_context():
//   0x4A (this type, which keeps the tag apart from a commit tag), total_len u16, blob_crc32 u32,
//   the values of the MODEL_BEGIN the nonce answered.
struct ModelAuth {
  uint8_t hmac[kHmacSize];
};
const uint8_t kModelAuthContextSize = 7;

// MODEL_READ 0x47, 3 bytes.
struct ModelRead {
  uint16_t offset;
  uint8_t len;  // 1..kMaxModelData
};

// GET_CONFIG 0x49, 1 byte.
struct GetConfig {
  uint8_t key;
};

// ---------------------------------------------------------------------------------------------
// Codecs.

namespace detail {
inline bool i24_fits(int32_t v) { return v >= kInt24Min && v <= kInt24Max; }
inline void copy_bytes(uint8_t* dst, const uint8_t* src, uint8_t n) {
  for (uint8_t i = 0; i < n; ++i) dst[i] = src[i];
}
}  // namespace detail

// The SAMPLE layout from separate fields (the firmware writes its own arrays this way, without a
// Sample copy); encode_sample() is this with a Sample's fields.
inline uint8_t encode_sample_fields(uint32_t sample_index, uint32_t time_ms, uint16_t speed_rpm,
                                    const int32_t* temp_mK, const uint8_t* channel_status,
                                    const int32_t* predicted_mK, uint8_t overall, uint8_t* p) {
  if ((overall & kOverallReservedMask) != 0) return 0;
  for (uint8_t i = 0; i < kChannels; ++i) {
    if (!detail::i24_fits(temp_mK[i]) || !detail::i24_fits(predicted_mK[i])) return 0;
  }
  put_le32(p, sample_index);
  put_le32(p + 4, time_ms);
  put_le16(p + 8, speed_rpm);
  uint8_t* q = p + 10;
  for (uint8_t i = 0; i < kChannels; ++i, q += 3) put_le24(q, temp_mK[i]);
  for (uint8_t i = 0; i < kChannels; ++i) *q++ = channel_status[i];
  for (uint8_t i = 0; i < kChannels; ++i, q += 3) put_le24(q, predicted_mK[i]);
  *q = overall;
  return kSampleSize;
}

inline uint8_t encode_sample(const Sample& m, uint8_t* p) {
  return encode_sample_fields(m.sample_index, m.time_ms, m.speed_rpm, m.temp_mK, m.channel_status, m.predicted_mK,
                              m.overall, p);
}

inline bool decode_sample(const uint8_t* p, uint8_t len, Sample& m) {
  if (len != kSampleSize) return false;
  m.sample_index = get_le32(p);
  m.time_ms = get_le32(p + 4);
  m.speed_rpm = get_le16(p + 8);
  const uint8_t* q = p + 10;
  for (uint8_t i = 0; i < kChannels; ++i, q += 3) m.temp_mK[i] = get_le24s(q);
  for (uint8_t i = 0; i < kChannels; ++i) m.channel_status[i] = *q++;
  for (uint8_t i = 0; i < kChannels; ++i, q += 3) m.predicted_mK[i] = get_le24s(q);
  m.overall = *q;
  return (m.overall & kOverallReservedMask) == 0;
}

inline uint8_t encode_info(const Info& m, uint8_t* p) {
  if (m.model_state >= kModelStateCount) return 0;
  p[0] = m.fw_major;
  p[1] = m.fw_minor;
  p[2] = m.fw_patch;
  p[3] = m.protocol_version;
  put_le32(p + 4, m.device_id);
  put_le32(p + 8, m.model_crc);
  put_le32(p + 12, m.model_seq);
  put_le32(p + 16, m.uptime_s);
  p[20] = m.model_state;
  p[21] = m.reset_cause;
  put_le16(p + 22, m.adc_timeouts);
  put_le16(p + 24, m.frame_errors);
  put_le16(p + 26, m.kalman_rejects);
  put_le16(p + 28, m.sensor_faults);
  put_le16(p + 30, m.resets);
  put_le16(p + 32, m.watchdog_resets);
  return kInfoSize;
}

inline bool decode_info(const uint8_t* p, uint8_t len, Info& m) {
  if (len != kInfoSize) return false;
  m.fw_major = p[0];
  m.fw_minor = p[1];
  m.fw_patch = p[2];
  m.protocol_version = p[3];
  m.device_id = get_le32(p + 4);
  m.model_crc = get_le32(p + 8);
  m.model_seq = get_le32(p + 12);
  m.uptime_s = get_le32(p + 16);
  m.model_state = p[20];
  m.reset_cause = p[21];
  m.adc_timeouts = get_le16(p + 22);
  m.frame_errors = get_le16(p + 24);
  m.kalman_rejects = get_le16(p + 26);
  m.sensor_faults = get_le16(p + 28);
  m.resets = get_le16(p + 30);
  m.watchdog_resets = get_le16(p + 32);
  return m.model_state < kModelStateCount;
}

inline uint8_t encode_ack(const Ack& m, uint8_t* p) {
  if (m.status >= kNackCodeCount) return 0;
  p[0] = m.acked_seq;
  p[1] = m.acked_type;
  p[2] = m.status;
  put_le16(p + 3, m.detail);
  return kAckSize;
}

inline bool decode_ack(const uint8_t* p, uint8_t len, Ack& m) {
  if (len != kAckSize) return false;
  m.acked_seq = p[0];
  m.acked_type = p[1];
  m.status = p[2];
  m.detail = get_le16(p + 3);
  // Unknown status codes are rejected: a newer firmware's code must not be read as success.
  return m.status < kNackCodeCount;
}

inline uint8_t encode_auth_challenge(const AuthChallenge& m, uint8_t* p) {
  detail::copy_bytes(p, m.nonce, kNonceSize);
  return kNonceSize;
}

inline bool decode_auth_challenge(const uint8_t* p, uint8_t len, AuthChallenge& m) {
  if (len != kNonceSize) return false;
  detail::copy_bytes(m.nonce, p, kNonceSize);
  return true;
}

// Shared by MODEL_DATA and MODEL_CHUNK.
inline uint8_t encode_model_bytes(const ModelBytes& m, uint8_t* p) {
  if (m.len == 0 || m.len > kMaxModelData) return 0;
  if (static_cast<uint32_t>(m.offset) + m.len > kMaxModelBlobSize) return 0;
  put_le16(p, m.offset);
  detail::copy_bytes(p + 2, m.data, m.len);
  return static_cast<uint8_t>(2 + m.len);
}

inline bool decode_model_bytes(const uint8_t* p, uint8_t len, ModelBytes& m) {
  if (len < 3 || len > 2 + kMaxModelData) return false;
  m.offset = get_le16(p);
  m.len = static_cast<uint8_t>(len - 2);
  detail::copy_bytes(m.data, p + 2, m.len);
  return static_cast<uint32_t>(m.offset) + m.len <= kMaxModelBlobSize;
}

inline uint8_t encode_model_data(const ModelData& m, uint8_t* p) { return encode_model_bytes(m, p); }
inline bool decode_model_data(const uint8_t* p, uint8_t len, ModelData& m) {
  return decode_model_bytes(p, len, m);
}
inline uint8_t encode_model_chunk(const ModelChunk& m, uint8_t* p) {
  return encode_model_bytes(m, p);
}
inline bool decode_model_chunk(const uint8_t* p, uint8_t len, ModelChunk& m) {
  return decode_model_bytes(p, len, m);
}

// CONFIG and SET_CONFIG: key must be known and value inside its range.
inline uint8_t encode_config_value(const ConfigValue& m, uint8_t* p) {
  if (!config_value_valid(m.key, m.value)) return 0;
  p[0] = m.key;
  put_le32(p + 1, static_cast<uint32_t>(m.value));
  return kConfigValueSize;
}

inline bool decode_config_value(const uint8_t* p, uint8_t len, ConfigValue& m) {
  if (len != kConfigValueSize) return false;
  m.key = p[0];
  m.value = static_cast<int32_t>(get_le32(p + 1));
  return config_value_valid(m.key, m.value);
}

inline uint8_t encode_set_config(const ConfigValue& m, uint8_t* p) {
  return encode_config_value(m, p);
}
inline bool decode_set_config(const uint8_t* p, uint8_t len, ConfigValue& m) {
  return decode_config_value(p, len, m);
}
inline uint8_t encode_config(const ConfigValue& m, uint8_t* p) { return encode_config_value(m, p); }
inline bool decode_config(const uint8_t* p, uint8_t len, ConfigValue& m) {
  return decode_config_value(p, len, m);
}

inline bool speed_value_valid(uint16_t rpm) { return rpm <= kMaxSpeedRpm || rpm == kSpeedFromTach; }

inline uint8_t encode_set_speed(const SetSpeed& m, uint8_t* p) {
  if (!speed_value_valid(m.rpm)) return 0;
  put_le16(p, m.rpm);
  return 2;
}

inline bool decode_set_speed(const uint8_t* p, uint8_t len, SetSpeed& m) {
  if (len != 2) return false;
  m.rpm = get_le16(p);
  return speed_value_valid(m.rpm);
}

inline uint8_t encode_model_begin(const ModelBegin& m, uint8_t* p) {
  if (m.total_len == 0 || m.total_len > kMaxModelBlobSize) return 0;
  put_le16(p, m.total_len);
  put_le32(p + 2, m.blob_crc32);
  return 6;
}

inline bool decode_model_begin(const uint8_t* p, uint8_t len, ModelBegin& m) {
  if (len != 6) return false;
  m.total_len = get_le16(p);
  m.blob_crc32 = get_le32(p + 2);
  return m.total_len != 0 && m.total_len <= kMaxModelBlobSize;
}

inline uint8_t encode_model_commit(const ModelCommit& m, uint8_t* p) {
  detail::copy_bytes(p, m.hmac, kHmacSize);
  return kHmacSize;
}

inline bool decode_model_commit(const uint8_t* p, uint8_t len, ModelCommit& m) {
  if (len != kHmacSize) return false;
  detail::copy_bytes(m.hmac, p, kHmacSize);
  return true;
}

inline uint8_t encode_model_auth(const ModelAuth& m, uint8_t* p) {
  detail::copy_bytes(p, m.hmac, kHmacSize);
  return kHmacSize;
}

inline bool decode_model_auth(const uint8_t* p, uint8_t len, ModelAuth& m) {
  if (len != kHmacSize) return false;
  detail::copy_bytes(m.hmac, p, kHmacSize);
  return true;
}

// The bytes MODEL_AUTH's tag covers after the nonce (kModelAuthContextSize); host and module
// build them here, so both sides sign the same bytes in the same order.
inline void encode_model_auth_context(uint16_t total_len, uint32_t blob_crc32, uint8_t* out) {
  out[0] = static_cast<uint8_t>(MsgType::ModelAuth);
  put_le16(out + 1, total_len);
  put_le32(out + 3, blob_crc32);
}

inline bool model_read_valid(const ModelRead& m) {
  return m.len != 0 && m.len <= kMaxModelData &&
         static_cast<uint32_t>(m.offset) + m.len <= kMaxModelBlobSize;
}

inline uint8_t encode_model_read(const ModelRead& m, uint8_t* p) {
  if (!model_read_valid(m)) return 0;
  put_le16(p, m.offset);
  p[2] = m.len;
  return 3;
}

inline bool decode_model_read(const uint8_t* p, uint8_t len, ModelRead& m) {
  if (len != 3) return false;
  m.offset = get_le16(p);
  m.len = p[2];
  return model_read_valid(m);
}

inline uint8_t encode_get_config(const GetConfig& m, uint8_t* p) {
  ConfigRange r;
  if (!config_key_range(m.key, r)) return 0;
  p[0] = m.key;
  return 1;
}

inline bool decode_get_config(const uint8_t* p, uint8_t len, GetConfig& m) {
  if (len != 1) return false;
  m.key = p[0];
  ConfigRange r;
  return config_key_range(m.key, r);
}

// GET_INFO, ACK_ALARM and REBOOT carry no payload: decoding only checks the length.
inline bool decode_empty(uint8_t len) { return len == 0; }

// Valid payload length range of a type; false for unknown types. Lets the firmware answer
// UNKNOWN_TYPE and BAD_LENGTH before decoding.
inline bool payload_length_range(uint8_t type, uint8_t& min_len, uint8_t& max_len) {
  switch (static_cast<MsgType>(type)) {
    case MsgType::Sample: min_len = max_len = kSampleSize; return true;
    case MsgType::Info: min_len = max_len = kInfoSize; return true;
    case MsgType::Ack: min_len = max_len = kAckSize; return true;
    case MsgType::AuthChallenge: min_len = max_len = kNonceSize; return true;
    case MsgType::ModelData:
    case MsgType::ModelChunk: min_len = 3; max_len = 2 + kMaxModelData; return true;
    case MsgType::Config:
    case MsgType::SetConfig: min_len = max_len = kConfigValueSize; return true;
    case MsgType::GetInfo:
    case MsgType::AckAlarm:
    case MsgType::Reboot: min_len = max_len = 0; return true;
    case MsgType::SetSpeed: min_len = max_len = 2; return true;
    case MsgType::ModelBegin: min_len = max_len = 6; return true;
    case MsgType::ModelCommit:
    case MsgType::ModelAuth: min_len = max_len = kHmacSize; return true;
    case MsgType::ModelRead: min_len = max_len = 3; return true;
    case MsgType::GetConfig: min_len = max_len = 1; return true;
  }
  return false;
}

// ---------------------------------------------------------------------------------------------
// MODEL_CHUNK sizing for one BLE write.

// Largest n (1..min(available, kMaxModelData)) such that the ENCODED MODEL_CHUNK frame carrying
// data[0..n) at `offset` with sequence number `seq` is at most max_encoded wire bytes (flags and
// escapes included). The CRC's own escaping is accounted for exactly. Returns 0 if available is 0
// or not even one byte fits (cannot happen for max_encoded >= 20: the worst case is 20 bytes).
inline uint8_t model_chunk_fit(uint8_t seq, uint16_t offset, const uint8_t* data,
                               size_t available, size_t max_encoded = kBleWriteSize) {
  uint8_t payload[kMaxPayload];
  put_le16(payload, offset);
  size_t n = available < kMaxModelData ? available : kMaxModelData;
  // The fixed part alone is at least 2 flags + 8 raw bytes, so no more than max_encoded - 10
  // data bytes can ever fit; start there.
  if (max_encoded < 10) return 0;
  if (n > max_encoded - 10) n = max_encoded - 10;
  for (; n > 0; --n) {
    detail::copy_bytes(payload + 2, data, static_cast<uint8_t>(n));
    const size_t size = encoded_frame_size(type_code(MsgType::ModelChunk), seq, payload,
                                           static_cast<uint8_t>(2 + n));
    if (size <= max_encoded) return static_cast<uint8_t>(n);
  }
  return 0;
}

// Encodes one complete frame for a message struct via its codec. Returns the wire size or 0.
// Example: encode_message_frame(MsgType::Ack, seq, ack, encode_ack, out, sizeof out).
template <class Msg>
inline size_t encode_message_frame(MsgType type, uint8_t seq, const Msg& msg,
                                   uint8_t (*encode)(const Msg&, uint8_t*), uint8_t* out,
                                   size_t capacity) {
  uint8_t payload[kMaxPayload];
  const uint8_t len = encode(msg, payload);
  if (len == 0) return 0;
  return encode_frame(type_code(type), seq, payload, len, out, capacity);
}

}  // namespace wire
}  // namespace btsm

#endif  // BTSM_COMMON_WIRE_MESSAGES_HPP
