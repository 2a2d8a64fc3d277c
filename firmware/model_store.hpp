// Reduced-model store in EEPROM (two slots, see firmware/eeprom_layout.hpp) and the authenticated
// upload session (MODEL_BEGIN / MODEL_CHUNK / MODEL_COMMIT).
//
// RAM is the constraint: a 464-byte blob buffer does not fit next to everything else on the
// ATmega328P, so chunks are streamed straight into the inactive slot while HMAC and CRC run
// incrementally, and blobs are parsed from EEPROM field by field (the common decode() wants the
// whole blob in RAM), with the common validation parts (common/model_blob.hpp).
//
// Upload: begin() keeps the nonce and the announced length and CRC and writes nothing.
// authenticate() checks MODEL_AUTH's tag HMAC-SHA256(device key, nonce || context) (context =
// wire::encode_model_auth_context of that length and CRC); only a valid tag erases the target
// slot's commit marker and starts HMAC-SHA256(device key, nonce || blob), so a host without the
// key cannot change a single EEPROM byte. Chunks must then arrive in order; commit() checks the
// tag (constant time), the MODEL_BEGIN CRC-32 against the bytes read back from EEPROM, then parses
// and validates the blob into the caller's model. Only then are sequence, CRC and the commit
// marker written (marker last). Any failure leaves the old slot active; the nonce is single-use
// (every begin() needs a fresh one; a failed authenticate() and every commit() end the session).
#ifndef BTSM_FIRMWARE_MODEL_STORE_HPP
#define BTSM_FIRMWARE_MODEL_STORE_HPP

#include <stdint.h>
#include <string.h>

#include "common/byte_order.hpp"
#include "common/crc.hpp"
#include "common/hmac.hpp"
#include "common/model_blob.hpp"
#include "common/model_step.hpp"
#include "common/platform.hpp"
#include "common/wire_messages.hpp"
#include "firmware/eeprom_layout.hpp"
#include "firmware/eeprom_writer.hpp"

namespace btsm {

// What the firmware keeps of the active model in RAM (119 bytes instead of the 428-byte
// ReducedModel): the schedule without its speeds, the channel map and the detector limits.
// Coefficients and speeds stay in EEPROM (read on a speed change); ModelStore caches the
// coefficients for the current speed and stop phase.
struct ModelRuntime {
  uint8_t n_breakpoints;
  uint8_t ambient_channel;  // 0..4 or kModelAmbientNone
  uint8_t enabled_mask;
  uint16_t dt_ms;
  uint16_t stop_end_s[kModelEarlyStopPhases];
  uint8_t role[kModelChannels];
  ChannelLimits limits[kModelChannels];
  ChannelCoupling coupling;  // carriers (25 bytes: read every step, so kept in RAM)
};

template <class Storage>
class ModelStore {
 public:
  typedef wire::Nack Nack;

  explicit ModelStore(Storage& storage) : storage_(storage), writer_(storage) {}

  // ---- boot ---------------------------------------------------------------------------------

  // Finds the valid slot with the highest sequence number and loads it into `model`.
  // A slot whose CRC is fine but whose content fails validation is skipped (state Rejected when
  // nothing else is usable).
  void boot(ModelRuntime& rt) {
    active_slot_ = kNoSlot;
    state_ = wire::ModelState::None;
    uint8_t order[2] = {0, 1};
    uint32_t seq[2] = {0, 0};
    bool ok[2] = {slot_intact(0, seq[0]), slot_intact(1, seq[1])};
    // Serial-number order (RFC 1982): the sequence wraps from 0xFFFFFFFF to 0 and the wrapped slot
    // is still the newer one. Compared as plain numbers, a model flashed over seq 0xFFFFFFFF got
    // seq 0 and the old one came back at the next reset (probe 5).
    if (ok[0] && ok[1] && static_cast<int32_t>(seq[1] - seq[0]) > 0) {
      order[0] = 1;
      order[1] = 0;
    }
    next_seq_ = 1;
    for (uint8_t k = 0; k < 2; ++k) {
      if (ok[order[k]]) {
        next_seq_ = seq[order[k]] + 1;  // after the newest intact slot
        break;
      }
    }
    if (next_seq_ == 0) next_seq_ = 1;  // 0 is what INFO reports without an active model
    for (uint8_t k = 0; k < 2; ++k) {
      const uint8_t s = order[k];
      if (!ok[s]) continue;
      if (load_runtime(s, rt)) {
        active_slot_ = s;
        active_seq_ = seq[s];
        state_ = wire::ModelState::Active;
        return;
      }
      state_ = wire::ModelState::Rejected;
    }
  }

  wire::ModelState state() const { return state_; }
  bool active() const { return state_ == wire::ModelState::Active; }
  uint32_t active_seq() const { return active() ? active_seq_ : 0; }
  // CRC-32 stored inside the active blob (INFO model_crc), 0 without a model.
  uint32_t active_blob_crc() const {
    if (!active()) return 0;
    uint8_t b[4];
    read_bytes(static_cast<uint16_t>(eeprom_layout::blob_addr(active_slot_) + kBlobOffCrc), b, 4);
    return get_le32(b);
  }
  uint8_t read_active_byte(uint16_t offset) const {
    return storage_.read(static_cast<uint16_t>(eeprom_layout::blob_addr(active_slot_) + offset));
  }

  // ---- upload session -----------------------------------------------------------------------

  bool busy() const { return writer_.busy(); }
  // The one EEPROM writer of the firmware (the App queues configuration records on it too).
  EepromWriter<Storage, 58>& writer() { return writer_; }
  // Advances pending EEPROM writes; true when none are left.
  bool step() { return writer_.step(); }
  bool session_open() const { return session_ != kNoSession; }
  uint16_t expected_offset() const { return received_; }

  // Derives the session nonce from `seed` (16 bytes of entropy and counters): nonce = first 16
  // bytes of HMAC-SHA256(seed, "") -- computed with the session's own MAC context, so no second
  // SHA-256 context is needed on the stack.
  static constexpr uint8_t kNonceSize = 16;
  void derive_nonce(const uint8_t* seed, uint8_t* nonce) {
    uint8_t digest[kHmacSha256Size];
    mac_.init(seed, kNonceSize);
    mac_.final(digest);
    for (uint8_t i = 0; i < kNonceSize; ++i) nonce[i] = digest[i];
    secure_zero(digest, sizeof digest);
  }

  // Opens a session for a blob of total_len bytes with CRC-32 blob_crc and the nonce already sent
  // to the host (kNonceSize bytes). Writes nothing: the session waits for authenticate().
  Nack begin(uint16_t total_len, uint32_t blob_crc, const uint8_t* nonce) {
    if (busy()) return Nack::Busy;
    if (total_len != eeprom_layout::kBlobSize) return Nack::BadLength;
    session_ = kChallenged;
    expected_crc_ = blob_crc;
    memcpy(nonce_, nonce, kNonceSize);
    return Nack::Ok;
  }

  // MODEL_AUTH: `tag` must be HMAC-SHA256(key, nonce || auth context). A wrong tag ends the
  // session (the nonce is spent); a right one starts the blob MAC and erases the target slot's
  // commit marker before any blob byte changes -- the first EEPROM write of the upload.
  BTSM_NOINLINE Nack authenticate(const uint8_t* tag, const uint8_t* key, uint8_t key_len) {
    if (session_ != kChallenged) return Nack::NoSession;
    if (busy()) return Nack::Busy;
    session_ = kNoSession;
    uint8_t context[wire::kModelAuthContextSize];
    wire::encode_model_auth_context(eeprom_layout::kBlobSize, expected_crc_, context);
    start_mac(key, key_len);
    mac_.update(context, sizeof context);
    if (!mac_matches(tag)) return Nack::AuthFailed;
    start_mac(key, key_len);
    session_ = kReceiving;
    target_slot_ = active_slot_ == 0 ? 1 : 0;
    received_ = 0;
    running_crc_ = 0;
    const uint8_t erased[2] = {0xFF, 0xFF};
    writer_.queue(eeprom_layout::slot_addr(target_slot_), erased, 2);
    return Nack::Ok;
  }

  // Queues one chunk. `detail` gets the expected offset on BadOffset.
  Nack chunk(uint16_t offset, const uint8_t* data, uint8_t len, uint16_t& detail) {
    detail = 0;
    if (session_ != kReceiving) return Nack::NoSession;
    if (busy()) return Nack::Busy;
    if (offset != received_) {
      detail = received_;
      return Nack::BadOffset;
    }
    if (static_cast<uint32_t>(offset) + len > eeprom_layout::kBlobSize) {
      detail = eeprom_layout::kBlobSize;
      return Nack::BadOffset;
    }
    writer_.queue(static_cast<uint16_t>(eeprom_layout::blob_addr(target_slot_) + offset), data, len);
    mac_.update(data, len);
    running_crc_ = crc32(data, len, running_crc_);
    received_ = static_cast<uint16_t>(received_ + len);
    return Nack::Ok;
  }

  // Checks the tag and the stored blob, validates it and queues the slot header. On any failure
  // the session ends and the active slot stays in use.
  Nack commit(const uint8_t* tag, uint16_t& detail) {
    detail = 0;
    if (session_ != kReceiving) return Nack::NoSession;
    if (busy()) return Nack::Busy;
    session_ = kNoSession;  // single use, whatever happens next
    // Each step is its own out-of-line function so their buffers are never on the stack together
    // (2 KB of SRAM on the ATmega328P).
    const Nack stored = verify_tag_and_bytes(tag, detail);
    if (stored != Nack::Ok) return stored;
    const ModelCheck check = check_slot(target_slot_);
    if (!check.ok()) {
      detail = check.detail();
      // The wire's BLOB_VERSION covers "magic/version not understood"; the detail names the
      // version found (ModelCheck::channel).
      if (check.status == ModelStatus::kBadMagic) return Nack::BlobVersion;
      switch (model_status_class(check.status)) {
        case ModelStatusClass::kCrc: return Nack::BlobCrc;
        case ModelStatusClass::kVersion: return Nack::BlobVersion;
        default: return Nack::BlobInvalid;
      }
    }
    queue_slot_header();
    pending_activation_ = true;
    return Nack::Ok;
  }

  // After commit() returned Ok and step() finished the writes: switch to the new slot.
  bool activation_pending() const { return pending_activation_; }
  void activate_committed(ModelRuntime& rt) {
    load_runtime(target_slot_, rt);
    pending_activation_ = false;
    active_slot_ = target_slot_;
    active_seq_ = next_seq_;
    if (++next_seq_ == 0) next_seq_ = 1;  // 0 is what INFO reports without an active model
    state_ = wire::ModelState::Active;
  }

  void abort_session() { session_ = kNoSession; }

  // One model step (common/model_step.hpp): writes predicted temperatures (mK) and advances the
  // state. Out of line, as init_state: inlined into poll() (and so into main) their locals would
  // deepen the stack under everything else.
  BTSM_NOINLINE void step_model(const ModelRuntime& rt, ReducedModelState& st, uint16_t speed_rpm, int32_t ambient_mK,
                                int32_t* predicted_mK) {
    // The stop phase only matters while stopped (coefficients_at ignores it when running).
    const uint8_t phase = speed_rpm > 0 ? kModelEarlyStopPhases : stop_phase(rt.stop_end_s, st.stopped_ms);
    const ModelBreakpoint& p = coefficients(rt, speed_rpm, phase);
    step_with(p, rt.coupling, speed_rpm > 0, rt.ambient_channel, rt.enabled_mask, rt.dt_ms, st, ambient_mK, predicted_mK);
  }

  // Initial state from measured temperatures (common init_from_measurement): called once after
  // boot or a new model.
  BTSM_NOINLINE bool init_state(const ModelRuntime& rt, ReducedModelState& st, int32_t ambient_mK,
                                const int32_t* measured_mK) {
    if (!active()) return false;
    return init_from_measurement(rt.ambient_channel, rt.enabled_mask, st, ambient_mK, measured_mK);
  }

  // Parses and validates the blob of `slot` from EEPROM into `out` (same checks and order as the
  // common decode(): CRC, magic, version, reserved bytes, then validate()'s schedule, breakpoints,
  // stop poles, limits). The coefficients are checked 40 bytes at a time as they are read and not
  // kept (they stay in EEPROM): one 40-byte scratch buffer instead of a 428-byte ReducedModel on
  // the stack. `out` is modified even on failure.
  BTSM_NOINLINE ModelCheck load_slot(uint8_t slot, ModelRuntime& out) const {
    static_assert(BTSM_LITTLE_ENDIAN, "coefficients are read as little-endian int32");
    const uint16_t base = eeprom_layout::blob_addr(slot);
    uint32_t crc = 0;
    bool reserved_zero = true;
    for (uint16_t i = 0; i < kBlobOffCrc; ++i) {
      const uint8_t b = storage_.read(static_cast<uint16_t>(base + i));
      crc = crc32(&b, 1, crc);
      if (i >= kBlobOffReserved && b != 0) reserved_zero = false;
    }
    // One scratch area for the header, each breakpoint, the stop poles and each channel's limits.
    union {
      uint8_t bytes[kBlobBreakpointSize];
      ModelBreakpoint bp;
      int32_t stop_a[kModelEarlyStopPhases][kModelChannels];
    } scratch;
    static_assert(sizeof scratch.stop_a == kBlobOffRoles - kBlobOffStopPoles, "stop poles fit the scratch area");
    static_assert(sizeof scratch.bytes >= kBlobOffBreakpoints, "the header fits the scratch area");
    static_assert(sizeof scratch.bytes >= kBlobOffReserved - kBlobOffCarriers, "the couplings fit the scratch area");
    uint8_t* buf = scratch.bytes;
    read_bytes(static_cast<uint16_t>(base + kBlobOffCrc), buf, 4);
    if (crc != get_le32(buf)) return model_check(ModelStatus::kBadCrc);
    read_bytes(base, buf, kBlobOffBreakpoints);
    if (get_le32(buf + kBlobOffMagic) != kReducedModelMagic) return model_check(ModelStatus::kBadMagic);
    if (buf[kBlobOffVersion] != kReducedModelVersion) return model_check(ModelStatus::kBadVersion, 0xFF, buf[kBlobOffVersion]);
    if (!reserved_zero) return model_check(ModelStatus::kUnusedNotZero);
    ModelSchedule s;
    decode_schedule(buf, s);
    read_bytes(static_cast<uint16_t>(base + kBlobOffRoles), s.role, kModelChannels);
    read_bytes(static_cast<uint16_t>(base + kBlobOffCarriers), buf, kBlobOffReserved - kBlobOffCarriers);
    decode_coupling_from_fields(buf, s.coupling);
    ModelCheck c = validate_schedule(s);
    for (uint8_t i = 0; i < kModelMaxBreakpoints && c.ok(); ++i) {
      read_bytes(static_cast<uint16_t>(base + kBlobOffBreakpoints + kBlobBreakpointSize * i), buf, kBlobBreakpointSize);
      c = validate_breakpoint(scratch.bp, i, s);
    }
    if (!c.ok()) return c;
    read_bytes(static_cast<uint16_t>(base + kBlobOffStopPoles), buf, sizeof scratch.stop_a);
    c = validate_stop_poles(scratch.stop_a, s);
    if (!c.ok()) return c;
    for (uint8_t j = 0; j < kModelChannels; ++j) {
      // Channel j's fields (each field is an array over the channels).
      read_bytes(static_cast<uint16_t>(base + kBlobOffDrift + 2 * j), buf, 2);
      out.limits[j].drift_mK = get_le16(buf);
      read_bytes(static_cast<uint16_t>(base + kBlobOffLowDrift + 2 * j), buf, 2);
      out.limits[j].low_drift_mK = get_le16(buf);
      read_bytes(static_cast<uint16_t>(base + kBlobOffWarnEvidence + 2 * j), buf, 2);
      out.limits[j].warn_evidence = get_le16(buf);
      read_bytes(static_cast<uint16_t>(base + kBlobOffAlarmEvidence + 2 * j), buf, 2);
      out.limits[j].alarm_evidence = get_le16(buf);
      read_bytes(static_cast<uint16_t>(base + kBlobOffLowWarnEvidence + 2 * j), buf, 2);
      out.limits[j].low_warn_evidence = get_le16(buf);
      read_bytes(static_cast<uint16_t>(base + kBlobOffAbsLimits + 4 * j), buf, 4);
      out.limits[j].abs_limit_mK = static_cast<int32_t>(get_le32(buf));
      read_bytes(static_cast<uint16_t>(base + kBlobOffMaxRise + 2 * j), buf, 2);
      out.limits[j].max_rise_mK_per_min = get_le16(buf);
    }
    c = validate_limits(out.limits, s);
    out.n_breakpoints = s.n_breakpoints;
    out.ambient_channel = s.ambient_channel;
    out.enabled_mask = s.enabled_mask;
    out.dt_ms = s.dt_ms;
    for (uint8_t k = 0; k < kModelEarlyStopPhases; ++k) out.stop_end_s[k] = s.stop_end_s[k];
    for (uint8_t j = 0; j < kModelChannels; ++j) out.role[j] = s.role[j];
    out.coupling = s.coupling;
    return c;
  }

 private:
  enum Session : uint8_t { kNoSession, kChallenged, kReceiving };
  static constexpr uint8_t kNoSlot = 0xFF;
  // No model speed is 0xFFFF (wire::kSpeedFromTach is not a speed, the tach saturates at 65534).
  static constexpr uint16_t kNoCoefficients = 0xFFFF;

  // HMAC-SHA256(key, nonce || ...): the start of both tags of a session.
  BTSM_NOINLINE void start_mac(const uint8_t* key, uint8_t key_len) {
    mac_.init(key, key_len);
    mac_.update(nonce_, kNonceSize);
  }

  // Finishes the MAC and compares it with `tag` in constant time.
  BTSM_NOINLINE bool mac_matches(const uint8_t* tag) {
    uint8_t expected[kHmacSha256Size];
    mac_.final(expected);
    const bool ok = constant_time_equal(expected, tag, kHmacSha256Size);
    secure_zero(expected, sizeof expected);
    return ok;
  }

  BTSM_NOINLINE Nack verify_tag_and_bytes(const uint8_t* tag, uint16_t& detail) {
    if (!mac_matches(tag)) return Nack::AuthFailed;
    if (received_ != eeprom_layout::kBlobSize) {
      detail = received_;
      return Nack::BadLength;
    }
    if (running_crc_ != expected_crc_) return Nack::BlobCrc;
    uint32_t stored_crc = 0;
    for (uint16_t i = 0; i < eeprom_layout::kBlobSize; ++i) {
      const uint8_t b = storage_.read(static_cast<uint16_t>(eeprom_layout::blob_addr(target_slot_) + i));
      stored_crc = crc32(&b, 1, stored_crc);
    }
    if (stored_crc != running_crc_) return Nack::StoreFailed;  // EEPROM did not keep the bytes
    return Nack::Ok;
  }

  // Sequence + CRC first, commit marker last (two ordered writer segments).
  BTSM_NOINLINE void queue_slot_header() {
    uint8_t seq_le[4];
    put_le32(seq_le, next_seq_);
    uint8_t body[10];  // header bytes 2..11: seq, crc, blob length
    put_le32(body, next_seq_);
    put_le32(body + 4, slot_crc(seq_le));
    put_le16(body + 8, eeprom_layout::kBlobSize);
    const uint8_t marker[2] = {eeprom_layout::kMarker0, eeprom_layout::kMarker1};
    const uint16_t base = eeprom_layout::slot_addr(target_slot_);
    writer_.queue(static_cast<uint16_t>(base + eeprom_layout::kHdrSeq), body, 10);
    writer_.queue(static_cast<uint16_t>(base + eeprom_layout::kHdrMarker), marker, 2);
  }

  BTSM_NOINLINE void read_bytes(uint16_t addr, uint8_t* out, uint8_t n) const {
    for (uint8_t i = 0; i < n; ++i) out[i] = storage_.read(static_cast<uint16_t>(addr + i));
  }

  BTSM_NOINLINE uint32_t slot_crc(const uint8_t* seq_le) const {
    uint32_t crc = crc32(seq_le, 4);
    for (uint16_t i = 0; i < eeprom_layout::kBlobSize; ++i) {
      const uint8_t b = storage_.read(static_cast<uint16_t>(eeprom_layout::blob_addr(target_slot_) + i));
      crc = crc32(&b, 1, crc);
    }
    return crc;
  }

  // Marker, length and CRC(seq || blob) match.
  bool slot_intact(uint8_t slot, uint32_t& seq) const {
    uint8_t h[eeprom_layout::kSlotHeaderSize];
    read_bytes(eeprom_layout::slot_addr(slot), h, eeprom_layout::kSlotHeaderSize);
    if (h[0] != eeprom_layout::kMarker0 || h[1] != eeprom_layout::kMarker1) return false;
    if (get_le16(h + eeprom_layout::kHdrLen) != eeprom_layout::kBlobSize) return false;
    seq = get_le32(h + eeprom_layout::kHdrSeq);
    uint32_t crc = crc32(h + eeprom_layout::kHdrSeq, 4);
    for (uint16_t i = 0; i < eeprom_layout::kBlobSize; ++i) {
      const uint8_t b = storage_.read(static_cast<uint16_t>(eeprom_layout::blob_addr(slot) + i));
      crc = crc32(&b, 1, crc);
    }
    return crc == get_le32(h + eeprom_layout::kHdrCrc);
  }

  // Full validation into a scratch runtime (commit: the active model stays untouched).
  BTSM_NOINLINE ModelCheck check_slot(uint8_t slot) const {
    ModelRuntime tmp;
    return load_slot(slot, tmp);
  }

  // The active model's coefficients at speed_rpm and stop phase `phase`. They are kept until the
  // speed or the phase changes (the speed rarely does between sweeps: the tach's dead-band keeps
  // jitter from looking like a change) or another model is loaded.
  const ModelBreakpoint& coefficients(const ModelRuntime& rt, uint16_t speed_rpm, uint8_t phase) {
    if (speed_rpm != coeff_speed_rpm_ || phase != coeff_phase_) refresh_coefficients(rt, speed_rpm, phase);
    return coeff_;
  }

  // Reads breakpoint lo straight into the cache and, inside a segment, interpolates towards
  // breakpoint hi member by member as its bytes come from EEPROM (common interpolate() does the
  // same per member: the same integers), without a second 40-byte buffer; in an early stop phase
  // it reads that phase's poles instead. Only the channels with a model of their own are touched
  // (step_with skips the others, which keep lo's value) -- as common coefficients_at().
  BTSM_NOINLINE void refresh_coefficients(const ModelRuntime& rt, uint16_t speed_rpm, uint8_t phase) {
    static_assert(sizeof(ModelBreakpoint) == kBlobBreakpointSize && sizeof(ChannelCoeffs) == kBlobChannelCoeffSize,
                  "ModelBreakpoint must be the blob's ten little-endian int32 in member order");
    static_assert(BTSM_LITTLE_ENDIAN, "coefficients are read as little-endian int32");
    const uint16_t blob = eeprom_layout::blob_addr(active_slot_);
    uint16_t speeds[kModelMaxBreakpoints];  // little-endian u16 in place (the static_assert above)
    read_bytes(static_cast<uint16_t>(blob + kBlobOffSpeeds), reinterpret_cast<uint8_t*>(speeds), sizeof speeds);
    const SpeedSegment seg = find_segment(speeds, rt.n_breakpoints, speed_rpm);
    const uint16_t first = static_cast<uint16_t>(blob + kBlobOffBreakpoints);
    uint8_t* out = reinterpret_cast<uint8_t*>(&coeff_);
    read_bytes(static_cast<uint16_t>(first + kBlobBreakpointSize * seg.lo), out, kBlobBreakpointSize);
    // The channels with a model of their own (step_with skips the others).
    uint8_t channels = static_cast<uint8_t>(rt.enabled_mask & 0x1FU);
    if (rt.ambient_channel < kModelChannels) channels = static_cast<uint8_t>(channels & ~(1U << rt.ambient_channel));
    if (!seg.running && phase < kModelEarlyStopPhases) {
      // An early stop phase: its poles replace breakpoint 0's.
      uint16_t a = static_cast<uint16_t>(blob + kBlobOffStopPoles + 4 * kModelChannels * phase);
      for (uint8_t j = 0; j < kModelChannels; ++j, a += 4, out += kBlobChannelCoeffSize)
        if ((channels >> j) & 1U) read_bytes(a, out, 4);
    } else if (seg.frac_q16 != 0) {
      // Bit k: member k is needed (2 j: a of channel j, 2 j + 1: its b).
      uint16_t needed = 0;
      for (uint8_t j = 0; j < kModelChannels; ++j)
        if ((channels >> j) & 1U) needed = static_cast<uint16_t>(needed | (3U << (2 * j)));
      uint16_t hi = static_cast<uint16_t>(first + kBlobBreakpointSize * seg.hi);
      for (uint8_t k = 0; k < 2 * kModelChannels; ++k, hi += 4, out += 4, needed >>= 1) {
        if ((needed & 1U) == 0) continue;
        union {
          int32_t v;
          uint8_t b[4];
        } p1;
        for (uint8_t i = 0; i < 4; ++i) p1.b[i] = storage_.read(static_cast<uint16_t>(hi + i));
        int32_t p0;
        memcpy(&p0, out, 4);
        p0 = detail_rm::lerp_q(p0, p1.v, seg.frac_q16);
        memcpy(out, &p0, 4);
      }
    }
    coeff_speed_rpm_ = speed_rpm;
    coeff_phase_ = phase;
  }

  // Validates the slot and copies the schedule and limits (false: slot invalid, rt untouched).
  bool load_runtime(uint8_t slot, ModelRuntime& rt) {
    ModelRuntime tmp;
    if (!load_slot(slot, tmp).ok()) return false;
    coeff_speed_rpm_ = kNoCoefficients;
    rt = tmp;
    return true;
  }

  Storage& storage_;
  EepromWriter<Storage, 58> writer_;
  HmacSha256 mac_;
  ModelBreakpoint coeff_;  // at coeff_speed_rpm_ and stop phase coeff_phase_ (step_model)
  uint16_t coeff_speed_rpm_ = kNoCoefficients;
  uint8_t coeff_phase_ = 0;
  uint8_t nonce_[kNonceSize];  // of the open session, kept from begin() until authenticate()
  uint32_t expected_crc_ = 0;
  uint32_t running_crc_ = 0;
  uint32_t next_seq_ = 1;
  uint32_t active_seq_ = 0;
  uint16_t received_ = 0;
  uint8_t active_slot_ = kNoSlot;
  uint8_t target_slot_ = 0;
  Session session_ = kNoSession;
  wire::ModelState state_ = wire::ModelState::None;
  bool pending_activation_ = false;
};

}  // namespace btsm

#endif
