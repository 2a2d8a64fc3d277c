#pragma once
// In-process fake BTSM module for the link tests: speaks the wire protocol with the common
// codecs over any stream fd (pty master, socketpair), streams SAMPLEs whose content is a pure
// function of sample_index (so a test can check every accepted sample bit for bit), and
// implements the model upload with the contract's two-phase commit: MODEL_BEGIN issues a fresh
// single-use nonce, MODEL_AUTH proves the key (HMAC over nonce || 0x4A || len || crc) and only
// then opens the staging area, chunks fill it strictly in order, MODEL_COMMIT checks length,
// CRC-32, HMAC-SHA256(key, nonce || blob) and the blob itself and only then replaces the active
// model. Any failure ends the upload session and keeps the old model.
// Not App<NativeBoard> (test_sim_module.cpp): it cannot be told to send index-derived samples, BUSY, an old NACK, pause or speak an older firmware's upload.
#include "common/wire_frame.hpp"
#include "common/wire_messages.hpp"

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

namespace btsm::test {

// The key a FakeModule starts with: the firmware's development key 00 01 .. 1F (device_key.hpp).
std::array<uint8_t, 32> fake_module_key();

struct FakeModuleOptions {
  uint32_t device_id = 0x0000DE70;
  std::array<uint8_t, 32> key = fake_module_key();
  std::chrono::milliseconds sample_period{10};
  uint32_t first_sample_index = 0;
  bool stream_samples = true;
  bool answer_get_config = true;            // false: NACK UNKNOWN_TYPE like an older firmware
  uint32_t sample_time_step_ms = 5000;      // module time between samples
  uint32_t busy_every = 0;                  // answer every Nth MODEL_CHUNK with BUSY (0 = never)
  bool legacy_upload = false;               // a firmware before MODEL_AUTH: chunks right after MODEL_BEGIN
  // The link dies at an accepted MODEL_COMMIT: before its ACK is sent, or right after it.
  enum class HangUp { kNever, kBeforeCommitAck, kAfterCommitAck };
  HangUp hang_up = HangUp::kNever;
};

class FakeModule {
 public:
  // Takes ownership of fd.
  FakeModule(int fd, FakeModuleOptions opts = {});
  ~FakeModule();
  void start();
  void stop();

  // Deterministic sample content for index i (what the module sends).
  static wire::Sample sample_for(uint32_t index, uint16_t speed_rpm, uint32_t time_step_ms);

  std::vector<uint8_t> active_model() const;
  uint32_t model_seq() const;
  uint32_t commits_accepted() const;
  uint32_t commits_refused() const;
  // Blob bytes ever accepted into the staging area (the fake's "EEPROM writes" of uploads).
  uint64_t staged_bytes() const;
  uint16_t speed() const;
  uint32_t samples_sent() const;
  // Every MODEL_COMMIT payload received, in order (to replay one).
  std::vector<std::vector<uint8_t>> commit_payloads() const;
  // Simulates a reset: sample index starts again at 0 (model kept, as in EEPROM).
  void restart();
  // Pauses or resumes the sample stream.
  void set_streaming(bool on);
  // Replaces the fd (after a "reconnect" of the test's link); takes ownership.
  void replace_fd(int fd);

 private:
  void run();
  void handle(uint8_t type, uint8_t seq, const uint8_t* p, uint8_t len);
  void send(wire::MsgType type, uint8_t seq, const uint8_t* payload, uint8_t len);
  void ack(uint8_t seq, uint8_t type, wire::Nack status, uint16_t detail = 0);
  void end_upload();
  void hang_up();

  FakeModuleOptions opts_;
  std::atomic<int> fd_;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<bool> streaming_{true};
  mutable std::mutex mu_;
  wire::FrameDecoder decoder_;
  // state (under mu_)
  uint32_t next_index_;
  uint32_t time_ms_ = 1000;
  uint16_t speed_ = 0;
  uint32_t model_seq_ = 0;
  std::vector<uint8_t> active_;
  bool upload_challenged_ = false;  // MODEL_BEGIN answered, MODEL_AUTH not yet
  bool upload_open_ = false;        // authenticated: chunks are accepted
  uint64_t staged_bytes_ = 0;
  std::array<uint8_t, 16> nonce_{};
  std::vector<uint8_t> staging_;
  uint16_t staging_len_ = 0;
  uint32_t staging_crc_ = 0;
  uint32_t accepted_ = 0, refused_ = 0, sent_ = 0;
  uint32_t nonce_counter_ = 0;
  uint32_t chunk_counter_ = 0;
  int32_t config_[256] = {};
  std::vector<std::vector<uint8_t>> commits_;
};

// A valid 464-byte reduced-model blob; `variant` changes its coefficients (different CRC).
std::vector<uint8_t> make_test_blob(int variant);

}  // namespace btsm::test
