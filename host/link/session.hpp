#pragma once
// The host side of the BTSM protocol over any Transport: frame decoding with the common
// decoder, SAMPLE sequence tracking (a lost sample is reported as a gap, never invented),
// requests with retries on timeout, and reply matching by sequence number and type.
//
// Reply convention: the module answers request (type T, seq s) with ACK{acked_seq s,
// acked_type T, status} or, for GET_INFO / MODEL_BEGIN / MODEL_READ / GET_CONFIG, with the data
// frame (INFO / AUTH_CHALLENGE / MODEL_DATA / CONFIG) carrying header seq s. A retry uses a new
// seq, so a late answer to an abandoned attempt is never taken for the answer to the current one.
#include "common/wire_frame.hpp"
#include "common/wire_messages.hpp"
#include "host/link/link_error.hpp"
#include "host/link/transport.hpp"

#include <deque>
#include <optional>
#include <vector>

namespace btsm::link {

struct SessionOptions {
  Millis reply_timeout{2000};  // per attempt, ms
  int retries = 3;             // extra attempts after a timeout or a BUSY answer (other NACKs are final)
};

// A refused request: the module answered with a NACK code.
class NackError : public LinkError {
 public:
  NackError(uint8_t request_type, uint8_t code, uint16_t detail);
  uint8_t request_type() const { return request_type_; }
  uint8_t code() const { return code_; }
  uint16_t detail() const { return detail_; }

 private:
  uint8_t request_type_, code_;
  uint16_t detail_;
};

struct Frame {
  uint8_t type = 0;
  uint8_t seq = 0;
  std::vector<uint8_t> payload;
};

// Inclusive range of sample_index values that never arrived.
struct SampleGap {
  uint32_t first = 0, last = 0;
  uint64_t count() const { return static_cast<uint64_t>(last) - first + 1; }
};

// Follows SAMPLE.sample_index. The module numbers sweeps from 0 after every reset, so an index
// below the expected one means the module restarted (reported, and the samples before the
// first one of the new run that are missing are reported as a gap too). A repeat of the last
// index is a duplicate and is dropped.
class SampleTracker {
 public:
  struct Result {
    bool accept = true;          // false for a duplicate
    bool restarted = false;      // the module reset since the previous sample
    std::optional<SampleGap> gap;
  };
  Result observe(uint32_t index);
  uint64_t received() const { return received_; }
  uint64_t lost() const { return lost_; }
  uint64_t restarts() const { return restarts_; }
  uint64_t duplicates() const { return duplicates_; }
  const std::vector<SampleGap>& gaps() const { return gaps_; }

 private:
  std::optional<uint32_t> last_;
  uint64_t received_ = 0, lost_ = 0, restarts_ = 0, duplicates_ = 0;
  std::vector<SampleGap> gaps_;
};

struct SampleEvent {
  wire::Sample sample{};
  bool restarted = false;
  std::optional<SampleGap> gap;  // samples lost just before this one
};

class Session {
 public:
  explicit Session(Transport& transport, SessionOptions opts = {});

  Transport& transport() { return transport_; }
  const SessionOptions& options() const { return opts_; }

  // Next frame not consumed as a reply (SAMPLE, unsolicited INFO, ...); nullopt on timeout.
  std::optional<Frame> next_frame(Millis timeout);
  // Next SAMPLE (others are dropped and counted); updates the tracker; nullopt on timeout.
  // A SAMPLE whose payload does not decode is counted as invalid and never returned.
  std::optional<SampleEvent> next_sample(Millis timeout);

  // Requests. Each throws NackError on a NACK and LinkError(kTimeout) when all attempts timed out.
  wire::Info get_info();
  void set_speed(uint16_t rpm);
  void set_config(uint8_t key, int32_t value);
  wire::ConfigValue get_config(uint8_t key);
  void ack_alarm();
  void reboot();
  wire::AuthChallenge model_begin(uint16_t total_len, uint32_t blob_crc32);
  void model_chunk(uint16_t offset, std::span<const uint8_t> data);
  void model_commit(const uint8_t hmac[wire::kHmacSize]);
  wire::ModelData model_read(uint16_t offset, uint8_t len);

  // Sends a raw request and waits for its reply frame (an ACK, or `data_reply_type`). Returns the
  // reply frame; throws NackError on a NACK ACK. `attempts_used` receives how many attempts ran.
  Frame request(wire::MsgType type, std::span<const uint8_t> payload,
                std::optional<wire::MsgType> data_reply_type, int* attempts_used = nullptr);

  // The seq the next request will carry (the model chunk sizing needs it before encoding).
  uint8_t next_seq() const { return next_seq_; }

  // Max encoded frame size for MODEL_CHUNK: one 20-byte BLE write (whatever the transport).
  size_t chunk_frame_limit() const;

  SampleTracker& tracker() { return tracker_; }
  const wire::FrameCounters& frame_counters() const { return decoder_.counters(); }
  uint64_t invalid_payloads() const { return invalid_payloads_; }
  uint64_t ignored_frames() const { return ignored_frames_; }
  uint64_t busy_answers() const { return busy_answers_; }

  // After the transport was reopened: drop partial input (the tracker keeps counting).
  void resync();

 private:
  // Reads from the transport for up to `timeout`, decoding into inbox_. True if a frame arrived.
  bool pump(Millis timeout);
  uint8_t take_seq();
  void send_frame(uint8_t type, uint8_t seq, std::span<const uint8_t> payload);

  Transport& transport_;
  SessionOptions opts_;
  wire::FrameDecoder decoder_;
  std::deque<Frame> inbox_;
  SampleTracker tracker_;
  uint8_t next_seq_ = 1;
  uint64_t invalid_payloads_ = 0;
  uint64_t ignored_frames_ = 0;
  uint64_t busy_answers_ = 0;
};

// "SET_CONFIG" etc. for messages.
std::string msg_name(uint8_t type);

}  // namespace btsm::link
