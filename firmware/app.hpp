// The BTSM firmware core: acquisition -> RTD -> Kalman -> reduced model -> diagnosis -> SAMPLE
// frames, plus the command protocol (common/wire_messages.hpp) and the persistent stores.
//
// `template <class Board> class App` runs unchanged on the ATmega328P (boards/bluno_beetle) and on
// the native simulated board (boards/sim/native_board.hpp). poll() never waits: it does the work
// that is due and returns; idle_budget_ms() then says how long the caller may sleep (DOUT/RDY,
// received bytes and the 1 ms tick wake the MCU earlier). On AVR `main` loops poll() + idle sleep.
#ifndef BTSM_FIRMWARE_APP_HPP
#define BTSM_FIRMWARE_APP_HPP

#include <stdint.h>

#include "common/kalman.hpp"
#include "common/model_blob.hpp"
#include "common/model_step.hpp"
#include "common/rtd.hpp"
#include "common/sha256.hpp"
#include "common/wire_frame.hpp"
#include "common/wire_messages.hpp"
#include "firmware/acquisition.hpp"
#include "common/platform.hpp"
#include "firmware/config.hpp"
#include "common/device_key.hpp"
#include "firmware/diagnosis_stage.hpp"
#include "firmware/model_store.hpp"
#include "hal/contracts.hpp"

namespace btsm {

static constexpr uint8_t kFirmwareMajor = 0;
static constexpr uint8_t kFirmwareMinor = 2;
static constexpr uint8_t kFirmwarePatch = 0;

template <class Board>
class App {
  static_assert(hal::CheckBoard<Board>::value, "Board does not satisfy hal/contracts.hpp");
  typedef decltype(static_cast<Board*>(0)->spi) Spi;
  typedef decltype(static_cast<Board*>(0)->storage) Storage;

 public:
  static constexpr uint8_t kChannels = wire::kChannels;

  explicit App(Board& board)
      : board_(board), acq_(board.spi), store_(board.storage) {}

  void init() {
    board_.watchdog.enable();
    for (uint8_t j = 0; j < kChannels; ++j) {
      temp_mK_[j] = wire::kMissing;
      predicted_mK_[j] = wire::kMissing;
      status_[j] = 0;
    }
    uint8_t rec[config_record::kSize];
    for (uint8_t i = 0; i < config_record::kSize; ++i)
      rec[i] = board_.storage.read(static_cast<uint16_t>(eeprom_layout::kConfigAddr + i));
    config_.set_defaults();
    config_record::decode(rec, config_);  // keeps defaults when missing or corrupt
    load_and_bump_counters();
    store_.boot(model_);  // model_ = ModelRuntime (schedule + limits), coefficients stay in EEPROM
    model_initialised_ = false;
    board_.tach.set_pulses_per_rev(config_.tach_pulses_per_rev);
    apply_config();
    start_ms_ = board_.clock.millis();
    next_sweep_ms_ = start_ms_;
    model_last_step_ms_ = start_ms_;
    reset_cause_ = board_.power.reset_flags();
  }

  void poll() {
    board_.watchdog.kick();
    const uint32_t now = board_.clock.millis();
    uint32_t budget = 0xFFFFFFFFUL;

    // EEPROM work (model chunks/commit, configuration, counters): an ACK may wait for it.
    if (store_.busy()) {
      if (store_.step() && !store_.busy()) on_store_writes_done();
      budget = 1;
    }

    flush_output();
    // The stack-heaviest steps (the commit: HMAC tag check, then the blob validated breakpoint by
    // breakpoint from EEPROM) run here, at the shallowest call depth, not inside the frame handler
    // or the sweep processing.
    if (commit_pending_ && !store_.busy() && !out_pending_) run_commit();
    receive(now);

    const uint32_t acq_budget = acq_.poll(now);
    if (acq_budget < budget) budget = acq_budget;

    // Sweep schedule: drift-free, re-anchored when more than one period behind.
    if (static_cast<int32_t>(now - next_sweep_ms_) >= 0 && !sweep_in_progress_) {
      acq_.request_sweep();
      sweep_in_progress_ = true;
      sweep_time_ms_ = now;
      next_sweep_ms_ += config_.sample_period_ms;
      if (static_cast<int32_t>(now - next_sweep_ms_) >= 0) next_sweep_ms_ = now + config_.sample_period_ms;
    }
    if (acq_.sweep_ready()) {
      acq_.take_sweep();
      sweep_in_progress_ = false;
      process_sweep(now);
      sample_pending_ = true;
      budget = 0;
    }
    if (sample_pending_ && !out_pending_) {
      build_sample();
      sample_pending_ = false;
    }
    flush_output();
    // REBOOT: give the UART time to send the ACK (a 64-byte frame takes 6 ms at 115200 baud).
    if (reboot_pending_ && !out_pending_ && static_cast<int32_t>(now - reboot_at_ms_) >= 0) board_.power.reboot();

    if (!sweep_in_progress_) {
      const int32_t to_sweep = static_cast<int32_t>(next_sweep_ms_ - now);
      const uint32_t t = to_sweep > 0 ? static_cast<uint32_t>(to_sweep) : 0;
      if (t < budget) budget = t;
    }
    if ((rx_backlog_ && !out_pending_) || reboot_pending_) budget = budget > 1 ? 1 : budget;
    // A frame larger than the UART ring: refill every kTxRefillMs. A ring of >= 40 bytes holds
    // >= 3.4 ms of 115200 baud, so the line stays busy with a third of the polls of a 1 ms
    // refill. (Received bytes wait for the frame anyway.)
    if (out_pending_ && budget > kTxRefillMs) budget = kTxRefillMs;
    // Wake at least this often to kick the watchdog (2 s timeout).
    if (budget > kMaxSleepMs) budget = kMaxSleepMs;
    budget_ms_ = budget;
  }

  // How long the caller may sleep before the next poll() (ms); events wake it earlier.
  uint32_t idle_budget_ms() const { return budget_ms_; }

  // ---- inspection (tests, simulation) -------------------------------------------------------
  int32_t temperature_mK(uint8_t ch) const { return temp_mK_[ch]; }
  uint8_t channel_status(uint8_t ch) const { return status_[ch]; }
  const Acquisition<Spi>& acquisition() const { return acq_; }
  const FirmwareConfig& config() const { return config_; }
  wire::ModelState model_state() const { return store_.state(); }
  uint32_t model_seq() const { return store_.active_seq(); }
  uint32_t samples_sent() const { return sample_index_; }

 private:
  static constexpr uint8_t kMaxBytesPerPoll = 32;
  static constexpr uint32_t kRebootDelayMs = 50;
  static constexpr uint32_t kMaxSleepMs = 500;
  static constexpr uint32_t kTxRefillMs = 3;

  // ---- configuration ------------------------------------------------------------------------
  void apply_config() {
    AcquisitionSetup s;
    s.fs = config_.adc_fs;
    s.enabled_mask = config_.enabled_mask();
    s.r_ref_milliohm = config_.r_ref_milliohm;
    acq_.configure(s);
    // The fixed-point filter takes the configuration's integers as they are (common/kalman.hpp):
    // once settled an update is a subtraction, a comparison and one product.
    KalmanFixedParams kp;
    kp.q_mk2_per_s = config_.kalman_q;
    kp.r_mk2 = config_.kalman_r;
    kp.dt_ms = config_.sample_period_ms;
    kalman_setup_.configure(kp);
    for (uint8_t j = 0; j < kChannels; ++j) kalman_[j].reset();
    board_.tach.set_pulses_per_rev(config_.tach_pulses_per_rev);
    diagnosis_.configure(config_.alarm_latch != 0);
  }

  void save_config() {
    uint8_t rec[config_record::kSize];
    config_record::encode(config_, rec);
    store_.writer().queue(eeprom_layout::kConfigAddr, rec, config_record::kSize);
  }

  void load_and_bump_counters() {
    uint8_t c[6];
    for (uint8_t i = 0; i < 6; ++i) c[i] = board_.storage.read(static_cast<uint16_t>(eeprom_layout::kCountersAddr + i));
    if (crc16_ccitt(c, 4) == get_le16(c + 4)) {
      resets_ = get_le16(c);
      watchdog_resets_ = get_le16(c + 2);
    }
    if (resets_ != 0xFFFF) ++resets_;
    if (board_.watchdog.caused_last_reset() && watchdog_resets_ != 0xFFFF) ++watchdog_resets_;
    put_le16(c, resets_);
    put_le16(c + 2, watchdog_resets_);
    put_le16(c + 4, crc16_ccitt(c, 4));
    store_.writer().queue(eeprom_layout::kCountersAddr, c, 6);
  }

  // ---- measurement pipeline -----------------------------------------------------------------
  void process_sweep(uint32_t now) {
    // The channels' filters share their parameters, and after a rejection often also their
    // variance: one gain computation serves them all (exact, see common/kalman.hpp). Settled
    // filters use the precomputed steady-state gain, settling ones the precomputed first gains.
    KalmanFixedGainMemo memo;
    for (uint8_t j = 0; j < kChannels; ++j) process_channel(j, memo);
    update_speed();
    // The model advances on the sweeps' schedule (drift-free start times), not on the moment the
    // sweep finished: conversion timing jitters by a tick or two, and with dt equal to the sample
    // period a late sweep followed by an early one stepped twice and then not at all.
    run_model(sweep_time_ms_);
    diagnosis_.evaluate(store_.active() ? model_.limits : 0, temp_mK_, predicted_mK_, status_, config_.roles,
                        static_cast<uint32_t>(now - last_sweep_eval_ms_));
    last_sweep_eval_ms_ = now;
  }

  // One channel out of line: inlined into the loop (and with it into poll() and main()) the body
  // ran out of registers and spent ~200 cycles per channel moving spilled pointers.
  BTSM_NOINLINE void process_channel(uint8_t j, KalmanFixedGainMemo& memo) {
    uint8_t faults = 0;
    int32_t t_mK = wire::kMissing;
    if (config_.roles[j] == static_cast<uint8_t>(wire::ChannelRole::Disabled)) {
      status_[j] = wire::kStatusDisabled;
      temp_mK_[j] = wire::kMissing;
      kalman_[j].reset();
      return;
    }
    const ChannelReading& r = acq_.reading(j);
    faults = r.faults;
    if (faults == 0) {
      // IEC 60751 Pt1000, fixed point: the table inverse over -118...850 degC (common/rtd.hpp),
      // straight into the filter's unit (1/256 mK).
      const Pt1000FixedResult t = pt1000_temperature_q(r.r_q16);
      if (!t.ok()) {
        faults = t.status == RtdStatus::kBelowRange ? wire::kFaultShort : wire::kFaultOpen;
      } else {
        const KalmanOutcome o = kalman_[j].update(kalman_setup_, t.t, &memo);
        if (o == KalmanOutcome::kRejected) {
          faults |= wire::kFaultKalmanReject;
          if (kalman_rejects_ != 0xFFFF) ++kalman_rejects_;
        }
        // Nearest mK. An unusable filter (parameters out of its domain; the configuration
        // ranges exclude that) reports the unfiltered temperature rather than its empty estimate.
        if (o == KalmanOutcome::kInvalid) {
          t_mK = t.t >= 0 ? (t.t + 128) >> 8 : -((128 - t.t) >> 8);
        } else {
          t_mK = kalman_[j].estimate_mk();
        }
      }
    }
    const uint8_t hard_faults = faults & static_cast<uint8_t>(~wire::kFaultKalmanReject);
    if (hard_faults != 0) {
      t_mK = wire::kMissing;  // a faulty channel never reports a temperature
      kalman_[j].reset();
      if (sensor_faults_ != 0xFFFF) ++sensor_faults_;
    }
    temp_mK_[j] = t_mK;
    status_[j] = faults;
  }

  void update_speed() {
    if (speed_override_ == wire::kSpeedFromTach) {
      speed_rpm_ = board_.tach.rpm();
      speed_from_tach_ = true;
    } else {
      speed_rpm_ = speed_override_;
      speed_from_tach_ = false;
    }
  }

  void run_model(uint32_t now /* the sweep's start */) {
    if (!store_.active()) {
      for (uint8_t j = 0; j < kChannels; ++j) predicted_mK_[j] = wire::kMissing;
      model_last_step_ms_ = now;
      return;
    }
    const uint8_t amb_ch = model_.ambient_channel;
    const int32_t ambient = amb_ch < kChannels ? temp_mK_[amb_ch] : wire::kMissing;
    if (!model_initialised_) {
      // Every channel's model starts from its measured temperature (common init_from_measurement).
      model_initialised_ = store_.init_state(model_, model_state_, ambient, temp_mK_);
      model_last_step_ms_ = now;
    }
    // The poles are discretised for the blob's dt: step once per elapsed dt (catch up at most
    // 64 steps, e.g. after a long sample period), then report the latest prediction. Each step's
    // residuals go into the evidence.
    uint8_t steps = 0;
    bool stepped = false;
    while (model_initialised_ && static_cast<uint32_t>(now - model_last_step_ms_) >= model_.dt_ms && steps < 64) {
      store_.step_model(model_, model_state_, speed_rpm_, ambient, predicted_mK_);
      drop_mismatched_channels();
      diagnosis_.accumulate(model_.limits, temp_mK_, predicted_mK_);
      model_last_step_ms_ += model_.dt_ms;
      ++steps;
      stepped = true;
    }
    if (steps == 64) model_last_step_ms_ = now;
    if (!stepped && !have_prediction_) {
      // First sweep after (re)start: report the prediction of the current state without stepping.
      ReducedModelState probe = model_state_;
      store_.step_model(model_, probe, speed_rpm_, ambient, predicted_mK_);
      drop_mismatched_channels();
    }
    have_prediction_ = model_initialised_;
  }

  // The model's channel map against the module's channel roles: a channel whose configured role
  // is not the node its model was reduced for gets no prediction (and so no model checks, only
  // its absolute and rise limits), and none does when the ambient channel is not the ambient.
  // The host refuses such a model before flashing (flash-model); this covers roles changed later.
  void drop_mismatched_channels() {
    const ModelRuntime& s = model_;
    const bool ambient_ok = s.ambient_channel >= kChannels ||
                            config_.roles[s.ambient_channel] == static_cast<uint8_t>(wire::ChannelRole::Ambient);
    for (uint8_t j = 0; j < kChannels; ++j) {
      const uint8_t r = s.role[j];
      if (!ambient_ok || (r != kModelRoleUnchecked && r != kModelRoleNotModelled && r != config_.roles[j]))
        predicted_mK_[j] = wire::kMissing;
    }
  }

  // ---- output -------------------------------------------------------------------------------
  // Sink over one claimed piece of the UART's transmit space (board.serial.tx_claim): a compare
  // and a store per byte; the ring indices and the transmit interrupt are touched once per piece
  // (tx_commit), not per byte.
  struct SpanPut {
    uint8_t* p;
    uint8_t* end;
    BTSM_ALWAYS_INLINE bool operator()(uint8_t b) {
      if (p == end) return false;
      *p++ = b;
      return true;
    }
  };

  // The payload encoders write into the frame buffer behind the header (out_payload()), so the
  // raw frame is contiguous: wire::seal_raw_frame adds header and CRC in place.
  uint8_t* out_payload() { return out_frame_ + wire::kHeaderSize; }

  BTSM_NOINLINE void queue_frame(wire::MsgType type, uint8_t seq, uint8_t len) {
    out_len_ = wire::seal_raw_frame(out_frame_, wire::type_code(type), seq, len);
    wire::start_stuffed(out_cursor_);
    out_pending_ = true;
    flush_output();
  }

  // Streams the pending frame into the UART's transmit space; when it fills up the cursor
  // remembers where it stopped and the next poll continues from there (wire::resume_stuffed), so
  // frames larger than the ring need no second buffer and nothing is encoded or checksummed twice.
  // Inline test, out-of-line work: poll() calls this twice, and with -mcall-prologues an
  // out-of-line call that finds nothing to do still costs ~70 cycles of register saving.
  void flush_output() {
    if (out_pending_) continue_output();
  }
  BTSM_NOINLINE void continue_output() {
    // A ring hands out its free space in at most two pieces (before and after its wrap); the
    // loop ends when the frame is out or nothing is free.
    for (;;) {
      uint8_t n = 0;
      uint8_t* const start = board_.serial.tx_claim(n);
      if (n == 0) return;
      SpanPut put = {start, start + n};
      const bool done = wire::resume_stuffed(put, out_cursor_, out_frame_, out_len_);
      board_.serial.tx_commit(static_cast<uint8_t>(put.p - start));
      if (done) {
        out_pending_ = false;
        return;
      }
    }
  }

  BTSM_NOINLINE void send_ack(uint8_t seq, uint8_t type, wire::Nack status, uint16_t detail) {
    wire::Ack a;
    a.acked_seq = seq;
    a.acked_type = type;
    a.status = static_cast<uint8_t>(status);
    a.detail = detail;
    queue_frame(wire::MsgType::Ack, seq, wire::encode_ack(a, out_payload()));
  }

  // The request's ACK waits until the EEPROM writes it queued are done (on_store_writes_done).
  BTSM_NOINLINE void defer_ack(uint8_t seq, uint8_t type) {
    deferred_seq_ = seq;
    deferred_type_ = type;
    ack_after_write_ = true;
  }

  void send_deferred_ack() {
    ack_after_write_ = false;
    send_ack(deferred_seq_, deferred_type_, wire::Nack::Ok, 0);
  }

  void on_store_writes_done() {
    if (store_.activation_pending()) {
      store_.activate_committed(model_);
      model_initialised_ = false;
      have_prediction_ = false;
      diagnosis_.reset_evidence();
    }
    if (ack_after_write_) send_deferred_ack();
  }

  // Encodes straight from the pipeline's arrays into the frame buffer (no Sample copy).
  BTSM_NOINLINE void build_sample() {
    uint8_t status[kChannels];
    for (uint8_t j = 0; j < kChannels; ++j) status[j] = static_cast<uint8_t>(status_[j] | diagnosis_.state(j));
    uint8_t overall = diagnosis_.overall();
    if (diagnosis_.alarm_latched()) overall |= wire::kOverallAlarmLatched;
    if (store_.active()) overall |= wire::kOverallModelActive;
    if (speed_from_tach_) overall |= wire::kOverallSpeedFromTach;
    const uint32_t index = sample_index_++;
    const uint8_t len = wire::encode_sample_fields(index, sweep_time_ms_ - start_ms_, speed_rpm_, temp_mK_, status,
                                                   predicted_mK_, overall, out_payload());
    if (len != 0) queue_frame(wire::MsgType::Sample, static_cast<uint8_t>(index), len);
  }

  // ---- input --------------------------------------------------------------------------------
  void receive(uint32_t now) {
    rx_backlog_ = false;
    for (uint8_t n = 0; n < kMaxBytesPerPoll; ++n) {
      // One request at a time: wait while a response or a stored write is outstanding.
      if (out_pending_ || ack_after_write_ || commit_pending_ || store_.busy()) {
        rx_backlog_ = true;
        return;
      }
      uint8_t b;
      if (!board_.serial.read(b)) return;
      if (decoder_.push(b)) handle_frame(now);
    }
    rx_backlog_ = true;
  }

  void handle_frame(uint32_t now) {
    const uint8_t type = decoder_.type();
    const uint8_t seq = decoder_.seq();
    const uint8_t len = decoder_.payload_len();
    const uint8_t* p = decoder_.payload();
    uint8_t min_len = 0, max_len = 0;
    if (!wire::is_host_to_module(type) || !wire::payload_length_range(type, min_len, max_len)) {
      send_ack(seq, type, wire::Nack::UnknownType, 0);
      return;
    }
    if (len < min_len || len > max_len) {
      send_ack(seq, type, wire::Nack::BadLength, min_len);
      return;
    }
    switch (static_cast<wire::MsgType>(type)) {
      case wire::MsgType::GetInfo: send_info(seq, now); return;
      case wire::MsgType::SetSpeed: {
        wire::SetSpeed m;
        if (!wire::decode_set_speed(p, len, m)) return send_ack(seq, type, wire::Nack::BadValue, 0);
        speed_override_ = m.rpm;
        return send_ack(seq, type, wire::Nack::Ok, 0);
      }
      case wire::MsgType::SetConfig: {
        wire::ConfigValue m;
        if (!wire::decode_set_config(p, len, m)) return send_ack(seq, type, wire::Nack::BadValue, p[0]);
        if (store_.busy()) return send_ack(seq, type, wire::Nack::Busy, 0);
        config_.set(m.key, m.value);
        apply_config();
        save_config();
        return defer_ack(seq, type);  // ACK once the record is in EEPROM
      }
      case wire::MsgType::GetConfig: {
        wire::GetConfig m;
        wire::ConfigValue v;
        if (!wire::decode_get_config(p, len, m) || !config_.get(m.key, v.value))
          return send_ack(seq, type, wire::Nack::BadValue, p[0]);
        v.key = m.key;
        queue_frame(wire::MsgType::Config, seq, wire::encode_config(v, out_payload()));
        return;
      }
      case wire::MsgType::AckAlarm:
        diagnosis_.acknowledge();
        return send_ack(seq, type, wire::Nack::Ok, 0);
      case wire::MsgType::ModelBegin: return model_begin(seq, type, p, len, now);
      case wire::MsgType::ModelAuth: return model_auth(seq, type, p);
      case wire::MsgType::ModelChunk: {
        wire::ModelChunk m;
        if (!wire::decode_model_chunk(p, len, m)) return send_ack(seq, type, wire::Nack::BadOffset, 0);
        uint16_t detail = 0;
        const wire::Nack r = store_.chunk(m.offset, m.data, m.len, detail);
        if (r != wire::Nack::Ok) return send_ack(seq, type, r, detail);
        return defer_ack(seq, type);  // ACK once the chunk is in EEPROM
      }
      case wire::MsgType::ModelCommit:
        // The tag stays in the decoder buffer: no byte is pushed until run_commit() is done.
        deferred_seq_ = seq;
        deferred_type_ = type;
        commit_pending_ = true;
        return;
      case wire::MsgType::ModelRead: {
        wire::ModelRead m;
        if (!wire::decode_model_read(p, len, m) ||
            static_cast<uint32_t>(m.offset) + m.len > eeprom_layout::kBlobSize)
          return send_ack(seq, type, wire::Nack::BadOffset, eeprom_layout::kBlobSize);
        if (!store_.active()) return send_ack(seq, type, wire::Nack::NoSession, 0);
        wire::ModelData d;
        d.offset = m.offset;
        d.len = m.len;
        for (uint8_t i = 0; i < m.len; ++i) d.data[i] = store_.read_active_byte(static_cast<uint16_t>(m.offset + i));
        queue_frame(wire::MsgType::ModelData, seq, wire::encode_model_data(d, out_payload()));
        return;
      }
      case wire::MsgType::Reboot:
        send_ack(seq, type, wire::Nack::Ok, 0);
        reboot_pending_ = true;
        reboot_at_ms_ = now + kRebootDelayMs;
        return;
      default: return send_ack(seq, type, wire::Nack::UnknownType, 0);
    }
  }

  void run_commit() {
    commit_pending_ = false;
    uint16_t detail = 0;
    const wire::Nack r = store_.commit(decoder_.payload(), detail);
    if (r != wire::Nack::Ok) return send_ack(deferred_seq_, deferred_type_, r, detail);
    ack_after_write_ = true;  // ACK once the commit marker is written
  }

  void send_info(uint8_t seq, uint32_t now) {
    uint8_t rec[device_key::kRecordSize];
    board_.identity.read_key_record(rec, device_key::kRecordSize);
    wire::Info m;
    m.fw_major = kFirmwareMajor;
    m.fw_minor = kFirmwareMinor;
    m.fw_patch = kFirmwarePatch;
    m.protocol_version = wire::kProtocolVersion;
    m.device_id = device_key::record_valid(rec) ? get_le32(rec + device_key::kOffsetDeviceId) : 0;
    secure_zero(rec, sizeof rec);
    m.model_crc = store_.active_blob_crc();
    m.model_seq = store_.active_seq();
    m.uptime_s = (now - start_ms_) / 1000;
    m.model_state = static_cast<uint8_t>(store_.state());
    m.reset_cause = reset_cause_;
    const AcquisitionCounters& c = acq_.counters();
    m.adc_timeouts = c.adc_timeouts;
    m.frame_errors = decoder_.counters().frame_errors();
    m.kalman_rejects = kalman_rejects_;
    m.sensor_faults = sensor_faults_;
    m.resets = resets_;
    m.watchdog_resets = watchdog_resets_;
    queue_frame(wire::MsgType::Info, seq, wire::encode_info(m, out_payload()));
  }

  void model_begin(uint8_t seq, uint8_t type, const uint8_t* p, uint8_t len, uint32_t now) {
    wire::ModelBegin m;
    if (!wire::decode_model_begin(p, len, m))
      return send_ack(seq, type, wire::Nack::BadLength, eeprom_layout::kBlobSize);
    uint8_t rec[device_key::kRecordSize];
    board_.identity.read_key_record(rec, device_key::kRecordSize);
    const bool have_key = device_key::record_valid(rec);
    secure_zero(rec, sizeof rec);
    if (!have_key) return send_ack(seq, type, wire::Nack::AuthFailed, 1);  // no key: model writes refused
    // Fresh nonce: SHA-256 over conversion-noise bits, a counter that never repeats within a
    // boot, the boot count and timer entropy; first 16 bytes.
    uint8_t seed[16];
    put_le32(seed, acq_.entropy());
    put_le32(seed + 4, ++nonce_counter_);
    put_le16(seed + 8, resets_);
    put_le16(seed + 10, board_.identity.entropy_bits());
    put_le32(seed + 12, now);
    wire::AuthChallenge ch;
    store_.derive_nonce(seed, ch.nonce);
    const wire::Nack r = store_.begin(m.total_len, m.blob_crc32, ch.nonce);
    if (r != wire::Nack::Ok) return send_ack(seq, type, r, r == wire::Nack::BadLength ? eeprom_layout::kBlobSize : 0);
    queue_frame(wire::MsgType::AuthChallenge, seq, wire::encode_auth_challenge(ch, out_payload()));
  }

  // MODEL_AUTH: the payload is the tag (its length was checked). A session exists only after a
  // MODEL_BEGIN that found a valid key record, so the record is valid here.
  void model_auth(uint8_t seq, uint8_t type, const uint8_t* tag) {
    uint8_t rec[device_key::kRecordSize];
    board_.identity.read_key_record(rec, device_key::kRecordSize);
    const wire::Nack r = store_.authenticate(tag, rec + device_key::kOffsetKey, static_cast<uint8_t>(device_key::kKeySize));
    secure_zero(rec, sizeof rec);
    if (r != wire::Nack::Ok) return send_ack(seq, type, r, 0);
    defer_ack(seq, type);  // ACK once the target slot's commit marker is erased
  }

  Board& board_;
  Acquisition<Spi> acq_;
  ModelStore<Storage> store_;
  wire::FrameDecoder decoder_;
  FirmwareConfig config_;
  ModelRuntime model_;
  ReducedModelState model_state_;
  KalmanFixedSetup kalman_setup_;
  KalmanFixedChannel kalman_[kChannels];
  DiagnosisStage diagnosis_;
  // Set in init() (an initialiser image would sit in SRAM on AVR).
  int32_t temp_mK_[kChannels];
  int32_t predicted_mK_[kChannels];
  uint8_t status_[kChannels];
  uint8_t out_frame_[wire::kMaxRawFrame];  // raw frame being sent: header, payload, CRC
  wire::StuffCursor out_cursor_;
  uint32_t start_ms_ = 0;
  uint32_t next_sweep_ms_ = 0;
  uint32_t sweep_time_ms_ = 0;
  uint32_t last_sweep_eval_ms_ = 0;
  uint32_t model_last_step_ms_ = 0;
  uint32_t sample_index_ = 0;
  uint32_t nonce_counter_ = 0;
  uint32_t budget_ms_ = 0;
  uint32_t reboot_at_ms_ = 0;
  uint16_t speed_rpm_ = 0;
  uint16_t speed_override_ = wire::kSpeedFromTach;
  uint16_t resets_ = 0;
  uint16_t watchdog_resets_ = 0;
  uint16_t kalman_rejects_ = 0;
  uint16_t sensor_faults_ = 0;
  uint8_t out_len_ = 0;  // raw frame size
  uint8_t deferred_seq_ = 0;
  uint8_t deferred_type_ = 0;
  uint8_t reset_cause_ = 0;
  bool out_pending_ = false;
  bool commit_pending_ = false;
  bool sample_pending_ = false;
  bool sweep_in_progress_ = false;
  bool ack_after_write_ = false;
  bool reboot_pending_ = false;
  bool rx_backlog_ = false;
  bool speed_from_tach_ = false;
  bool model_initialised_ = false;
  bool have_prediction_ = false;
};

}  // namespace btsm

#endif
