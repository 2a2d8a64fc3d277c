#include "fake_module.hpp"

#include "common/crc.hpp"
#include "common/hmac.hpp"
#include "common/model_blob.hpp"
#include "common/device_key.hpp"
#include "host/thermal/model_reference.hpp"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace btsm::test {

using namespace btsm::wire;

std::array<uint8_t, 32> fake_module_key() {
  std::array<uint8_t, 32> key{};
  for (uint8_t i = 0; i < key.size(); ++i) key[i] = device_key::dev_key_byte(i);
  return key;
}

FakeModule::FakeModule(int fd, FakeModuleOptions opts) : opts_(opts), fd_(fd), next_index_(opts.first_sample_index) {
  streaming_ = opts.stream_samples;
  for (uint8_t k = 0; k < 255; ++k) {
    ConfigRange r{};
    if (config_key_range(k, r)) config_[k] = r.default_value;
  }
  // It reports the period it streams at, as the firmware does (monitor's silence watch reads it),
  // within the key's range (the fake streams faster than a module may be configured: 1 s at least).
  ConfigRange pr{};
  const auto period_key = static_cast<uint8_t>(wire::ConfigKey::SamplePeriodMs);
  if (config_key_range(period_key, pr))
    config_[period_key] = static_cast<int32_t>(std::clamp<long long>(opts.sample_period.count(), pr.min, pr.max));
}

FakeModule::~FakeModule() {
  stop();
  if (fd_ >= 0) ::close(fd_);
}

void FakeModule::start() {
  running_ = true;
  thread_ = std::thread([this] { run(); });
}

void FakeModule::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
}

void FakeModule::replace_fd(int fd) {
  std::lock_guard<std::mutex> l(mu_);
  const int old = fd_.exchange(fd);
  if (old >= 0) ::close(old);
  decoder_.reset();
}

Sample FakeModule::sample_for(uint32_t index, uint16_t speed_rpm, uint32_t time_step_ms) {
  Sample s{};
  s.sample_index = index;
  s.time_ms = 1000 + index * time_step_ms;
  s.speed_rpm = speed_rpm;
  for (uint8_t i = 0; i < kChannels; ++i) {
    s.temp_mK[i] = 20000 + 1000 * i + static_cast<int32_t>((index * 37 + i * 11) % 5000);
    s.channel_status[i] = 0;
    s.predicted_mK[i] = kMissing;
  }
  if (index % 7 == 3) {  // a probe fault now and then: missing value with its fault bits
    s.temp_mK[4] = kMissing;
    s.channel_status[4] = static_cast<uint8_t>(DiagState::SensorFault) | kFaultOpen;
  }
  s.overall = index % 7 == 3 ? static_cast<uint8_t>(DiagState::SensorFault) : 0;
  return s;
}

std::vector<uint8_t> FakeModule::active_model() const {
  std::lock_guard<std::mutex> l(mu_);
  return active_;
}
uint64_t FakeModule::staged_bytes() const {
  std::lock_guard<std::mutex> l(mu_);
  return staged_bytes_;
}

uint32_t FakeModule::model_seq() const {
  std::lock_guard<std::mutex> l(mu_);
  return model_seq_;
}
uint32_t FakeModule::commits_accepted() const {
  std::lock_guard<std::mutex> l(mu_);
  return accepted_;
}
uint32_t FakeModule::commits_refused() const {
  std::lock_guard<std::mutex> l(mu_);
  return refused_;
}
uint16_t FakeModule::speed() const {
  std::lock_guard<std::mutex> l(mu_);
  return speed_;
}
uint32_t FakeModule::samples_sent() const {
  std::lock_guard<std::mutex> l(mu_);
  return sent_;
}
std::vector<std::vector<uint8_t>> FakeModule::commit_payloads() const {
  std::lock_guard<std::mutex> l(mu_);
  return commits_;
}
void FakeModule::restart() {
  std::lock_guard<std::mutex> l(mu_);
  next_index_ = 0;
  upload_open_ = false;
}
void FakeModule::set_streaming(bool on) { streaming_ = on; }

void FakeModule::send(MsgType type, uint8_t seq, const uint8_t* payload, uint8_t len) {
  uint8_t out[kMaxEncodedFrame];
  const size_t n = encode_frame(type_code(type), seq, payload, len, out, sizeof out);
  if (n == 0) throw std::logic_error("fake module: frame does not encode");
  size_t done = 0;
  // Stops with the module: with no host reading, a full pty made the destructor wait for ever.
  while (done < n && running_) {
    const ssize_t w = ::write(fd_, out + done, n - done);
    if (w > 0) {
      done += static_cast<size_t>(w);
    } else if (w < 0 && (errno == EINTR || errno == EAGAIN)) {
      pollfd p{fd_, POLLOUT, 0};
      ::poll(&p, 1, 50);
    } else {
      return;  // the host side is gone; a real module would keep talking into the void
    }
  }
}

void FakeModule::ack(uint8_t seq, uint8_t type, Nack status, uint16_t detail) {
  Ack a{seq, type, static_cast<uint8_t>(status), detail};
  uint8_t p[kMaxPayload];
  send(MsgType::Ack, seq, p, encode_ack(a, p));
}

// Closes the module's end of the link (the host sees the device hang up); under mu_.
void FakeModule::hang_up() {
  const int old = fd_.exchange(-1);
  if (old >= 0) ::close(old);
}

void FakeModule::end_upload() {
  upload_challenged_ = false;
  upload_open_ = false;
  staging_.clear();
  nonce_.fill(0);
}

void FakeModule::handle(uint8_t type, uint8_t seq, const uint8_t* p, uint8_t len) {
  uint8_t out[kMaxPayload];
  uint8_t min_len = 0, max_len = 0;
  if (!payload_length_range(type, min_len, max_len) || !is_host_to_module(type) ||
      (type == type_code(MsgType::GetConfig) && !opts_.answer_get_config)) {
    ack(seq, type, Nack::UnknownType);
    return;
  }
  if (len < min_len || len > max_len) {
    ack(seq, type, Nack::BadLength, max_len);
    return;
  }
  switch (static_cast<MsgType>(type)) {
    case MsgType::GetInfo: {
      Info i{};
      i.fw_major = 0;
      i.fw_minor = 9;
      i.fw_patch = 1;
      i.protocol_version = kProtocolVersion;
      i.device_id = opts_.device_id;
      i.model_crc = active_.size() == kReducedModelBlobSize ? blob_stored_crc(active_.data()) : 0;
      i.model_seq = model_seq_;
      i.uptime_s = time_ms_ / 1000;
      i.model_state = static_cast<uint8_t>(active_.empty() ? ModelState::None : ModelState::Active);
      i.frame_errors = decoder_.counters().frame_errors();
      send(MsgType::Info, seq, out, encode_info(i, out));
      return;
    }
    case MsgType::SetSpeed: {
      SetSpeed s{};
      if (!decode_set_speed(p, len, s)) return ack(seq, type, Nack::BadValue);
      speed_ = s.rpm == kSpeedFromTach ? 0 : s.rpm;
      return ack(seq, type, Nack::Ok);
    }
    case MsgType::SetConfig: {
      ConfigValue c{};
      if (!decode_set_config(p, len, c)) return ack(seq, type, Nack::BadValue, p[0]);
      config_[c.key] = c.value;
      return ack(seq, type, Nack::Ok);
    }
    case MsgType::GetConfig: {
      GetConfig g{};
      if (!decode_get_config(p, len, g)) return ack(seq, type, Nack::BadValue, p[0]);
      ConfigValue c{g.key, config_[g.key]};
      send(MsgType::Config, seq, out, encode_config(c, out));
      return;
    }
    case MsgType::AckAlarm: return ack(seq, type, Nack::Ok);
    case MsgType::Reboot:
      ack(seq, type, Nack::Ok);
      next_index_ = 0;
      end_upload();
      return;
    case MsgType::ModelBegin: {
      ModelBegin b{};
      if (!decode_model_begin(p, len, b)) return ack(seq, type, Nack::BadValue);
      end_upload();
      // A firmware before MODEL_AUTH opened the staging area right here.
      upload_challenged_ = !opts_.legacy_upload;
      upload_open_ = opts_.legacy_upload;
      staging_len_ = b.total_len;
      staging_crc_ = b.blob_crc32;
      // Fresh nonce: a counter mixed through SHA-256 is unpredictable enough for a test double.
      ++nonce_counter_;
      uint8_t seed[8];
      put_le32(seed, nonce_counter_);
      put_le32(seed + 4, opts_.device_id);
      uint8_t digest[32];
      hmac_sha256(opts_.key.data(), opts_.key.size(), seed, sizeof seed, digest);
      std::memcpy(nonce_.data(), digest, 16);
      AuthChallenge ch{};
      std::memcpy(ch.nonce, nonce_.data(), 16);
      send(MsgType::AuthChallenge, seq, out, encode_auth_challenge(ch, out));
      return;
    }
    case MsgType::ModelAuth: {
      if (opts_.legacy_upload) return ack(seq, type, Nack::UnknownType);
      ModelAuth a{};
      decode_model_auth(p, len, a);
      if (!upload_challenged_) return ack(seq, type, Nack::NoSession);
      upload_challenged_ = false;  // one attempt per nonce
      uint8_t context[kModelAuthContextSize];
      encode_model_auth_context(staging_len_, staging_crc_, context);
      uint8_t tag[32];
      HmacSha256 mac;
      mac.init(opts_.key.data(), opts_.key.size());
      mac.update(nonce_.data(), nonce_.size());
      mac.update(context, sizeof context);
      mac.final(tag);
      if (!constant_time_equal(tag, a.hmac, 32)) {
        end_upload();
        return ack(seq, type, Nack::AuthFailed);
      }
      upload_open_ = true;
      return ack(seq, type, Nack::Ok);
    }
    case MsgType::ModelChunk: {
      ModelChunk c{};
      if (!decode_model_chunk(p, len, c)) return ack(seq, type, Nack::BadLength);
      if (!upload_open_) return ack(seq, type, Nack::NoSession);
      if (opts_.busy_every && ++chunk_counter_ % opts_.busy_every == 0) return ack(seq, type, Nack::Busy);
      if (c.offset != staging_.size() || c.offset + c.len > staging_len_)
        return ack(seq, type, Nack::BadOffset, static_cast<uint16_t>(staging_.size()));
      staging_.insert(staging_.end(), c.data, c.data + c.len);
      staged_bytes_ += c.len;
      return ack(seq, type, Nack::Ok);
    }
    case MsgType::ModelCommit: {
      commits_.emplace_back(p, p + len);
      ModelCommit c{};
      decode_model_commit(p, len, c);
      if (!upload_open_) {
        ++refused_;
        return ack(seq, type, Nack::NoSession);
      }
      // The nonce is spent whatever happens next: one commit per MODEL_BEGIN.
      const auto nonce = nonce_;
      const auto blob = staging_;
      end_upload();
      if (blob.size() != staging_len_) {
        ++refused_;
        return ack(seq, type, Nack::BadOffset, static_cast<uint16_t>(blob.size()));
      }
      uint8_t tag[32];
      HmacSha256 mac;
      mac.init(opts_.key.data(), opts_.key.size());
      mac.update(nonce.data(), nonce.size());
      mac.update(blob.data(), blob.size());
      mac.final(tag);
      if (!constant_time_equal(tag, c.hmac, 32)) {
        ++refused_;
        return ack(seq, type, Nack::AuthFailed);
      }
      if (crc32(blob.data(), blob.size()) != staging_crc_) {
        ++refused_;
        return ack(seq, type, Nack::BlobCrc);
      }
      ReducedModel m;
      const ModelCheck chk = decode(blob.data(), blob.size(), m);
      if (!chk.ok()) {
        ++refused_;
        const auto cls = model_status_class(chk.status);
        const Nack n = cls == ModelStatusClass::kVersion ? Nack::BlobVersion
                       : cls == ModelStatusClass::kCrc   ? Nack::BlobCrc
                       : cls == ModelStatusClass::kLength ? Nack::BadLength
                                                          : Nack::BlobInvalid;
        return ack(seq, type, n, chk.detail());
      }
      active_ = blob;
      ++model_seq_;
      ++accepted_;
      if (opts_.hang_up == FakeModuleOptions::HangUp::kBeforeCommitAck) return hang_up();
      ack(seq, type, Nack::Ok);
      if (opts_.hang_up == FakeModuleOptions::HangUp::kAfterCommitAck) {
        // Let the host read the ACK first: a pty drops what its slave has not read at hang-up.
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        hang_up();
      }
      return;
    }
    case MsgType::ModelRead: {
      ModelRead r{};
      if (!decode_model_read(p, len, r)) return ack(seq, type, Nack::BadOffset);
      if (r.offset + r.len > active_.size()) return ack(seq, type, Nack::BadOffset, static_cast<uint16_t>(active_.size()));
      ModelData d{};
      d.offset = r.offset;
      d.len = r.len;
      std::memcpy(d.data, active_.data() + r.offset, r.len);
      send(MsgType::ModelData, seq, out, encode_model_data(d, out));
      return;
    }
    default: return ack(seq, type, Nack::UnknownType);
  }
}

void FakeModule::run() {
  auto next_sample = std::chrono::steady_clock::now() + opts_.sample_period;
  uint8_t buf[256];
  while (running_) {
    const auto now = std::chrono::steady_clock::now();
    if (now >= next_sample) {
      std::lock_guard<std::mutex> l(mu_);
      if (streaming_) {
        const Sample s = sample_for(next_index_, speed_, opts_.sample_time_step_ms);
        uint8_t p[kMaxPayload];
        send(MsgType::Sample, static_cast<uint8_t>(next_index_), p, encode_sample(s, p));
        ++next_index_;
        ++sent_;
        time_ms_ = s.time_ms;
      }
      next_sample += opts_.sample_period;
      continue;
    }
    const int wait_ms = static_cast<int>(
        std::chrono::duration_cast<std::chrono::milliseconds>(next_sample - now).count()) + 1;
    pollfd pfd{fd_, POLLIN, 0};
    const int rc = ::poll(&pfd, 1, std::min(wait_ms, 20));
    if (rc <= 0) continue;
    const ssize_t n = ::read(fd_, buf, sizeof buf);
    if (n <= 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));  // link down: wait for replace_fd
      continue;
    }
    std::lock_guard<std::mutex> l(mu_);
    for (ssize_t i = 0; i < n; ++i) {
      if (decoder_.push(buf[i])) {
        uint8_t payload[kMaxPayload];
        const uint8_t len = decoder_.payload_len();
        std::memcpy(payload, decoder_.payload(), len);
        handle(decoder_.type(), decoder_.seq(), payload, len);
      }
    }
  }
}

std::vector<uint8_t> make_test_blob(int variant) {
  thermal::ReducedModelF64 f;
  f.dt_ms = 5000;
  f.n_breakpoints = 2;
  f.speed_rpm[0] = 0;
  f.speed_rpm[1] = static_cast<uint16_t>(6000 + 100 * variant);
  const uint8_t roles[kModelChannels] = {3, 4, 2, kModelRoleAmbient, kModelRoleNotModelled};
  f.enabled_mask = 0x0F;
  for (int j = 0; j < 3; ++j) {
    f.a[0][j] = 0.995;
    f.a[1][j] = 0.99 - 0.001 * variant;
    f.b_K[1][j] = 0.05 + 0.01 * j;
  }
  for (int j = 0; j < kModelChannels; ++j) f.role[j] = roles[j];
  ReducedModel m;
  const ModelCheck c = thermal::quantize(f, m);
  if (!c.ok()) throw std::logic_error(std::string("test blob does not quantize: ") + model_status_name(c.status));
  std::vector<uint8_t> blob(kReducedModelBlobSize);
  encode(m, blob.data());
  return blob;
}

}  // namespace btsm::test
