#include "host/link/session.hpp"

#include <fmt/format.h>

#include <thread>

namespace btsm::link {

using namespace btsm::wire;

std::string msg_name(uint8_t type) {
  const char* n = msg_type_name(type);
  return n ? n : fmt::format("type 0x{:02x}", type);
}

NackError::NackError(uint8_t request_type, uint8_t code, uint16_t detail)
    : LinkError(LinkErrorKind::kProtocol,
                fmt::format("module refused {}: {} ({}), detail 0x{:04x}", msg_name(request_type),
                            nack_name(code), nack_description(code), detail)),
      request_type_(request_type),
      code_(code),
      detail_(detail) {}

// --- SampleTracker ---------------------------------------------------------------------------
SampleTracker::Result SampleTracker::observe(uint32_t index) {
  Result r;
  if (last_ && index == *last_) {
    ++duplicates_;
    r.accept = false;
    return r;
  }
  uint32_t expected = 0;
  if (last_) {
    if (index < *last_ + 1ULL || *last_ == UINT32_MAX) {
      // Went backwards: the module restarted and counts from 0 again.
      r.restarted = true;
      ++restarts_;
      expected = 0;
    } else {
      expected = *last_ + 1;
    }
  } else {
    expected = index;  // the first sample we see defines the start, nothing before it is "lost"
  }
  if (index > expected) {
    r.gap = SampleGap{expected, index - 1};
    lost_ += r.gap->count();
    gaps_.push_back(*r.gap);
  }
  last_ = index;
  ++received_;
  return r;
}

// --- Session ---------------------------------------------------------------------------------
Session::Session(Transport& transport, SessionOptions opts) : transport_(transport), opts_(opts) {}

uint8_t Session::take_seq() {
  const uint8_t seq = next_seq_;
  // Skip 0 (easier to spot in captures) and the values that need escaping, so every seq has
  // the same encoded size and a chunk sized for one seq still fits one BLE write on a retry.
  do {
    ++next_seq_;
  } while (next_seq_ == 0 || needs_escape(next_seq_));
  return seq;
}

void Session::resync() {
  decoder_.reset();
  inbox_.clear();
}

size_t Session::chunk_frame_limit() const {
  return std::min<size_t>(kBleWriteSize, transport_.max_write_size());
}

bool Session::pump(Millis timeout) {
  uint8_t buf[256];
  const size_t n = transport_.read(buf, timeout);
  bool got = false;
  for (size_t i = 0; i < n; ++i) {
    if (decoder_.push(buf[i])) {
      Frame f;
      f.type = decoder_.type();
      f.seq = decoder_.seq();
      f.payload.assign(decoder_.payload(), decoder_.payload() + decoder_.payload_len());
      inbox_.push_back(std::move(f));
      got = true;
    }
  }
  return got;
}

std::optional<Frame> Session::next_frame(Millis timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    if (!inbox_.empty()) {
      Frame f = std::move(inbox_.front());
      inbox_.pop_front();
      return f;
    }
    const auto left = std::chrono::duration_cast<Millis>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return std::nullopt;
    pump(left);
  }
}

std::optional<SampleEvent> Session::next_sample(Millis timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    const auto left = std::chrono::duration_cast<Millis>(deadline - std::chrono::steady_clock::now());
    auto f = next_frame(std::max(left, Millis(0)));
    if (!f) return std::nullopt;
    if (f->type != type_code(MsgType::Sample)) {
      ++ignored_frames_;
      continue;
    }
    SampleEvent ev;
    if (!decode_sample(f->payload.data(), static_cast<uint8_t>(f->payload.size()), ev.sample)) {
      ++invalid_payloads_;
      continue;
    }
    const auto r = tracker_.observe(ev.sample.sample_index);
    if (!r.accept) continue;
    ev.restarted = r.restarted;
    ev.gap = r.gap;
    return ev;
  }
}

void Session::send_frame(uint8_t type, uint8_t seq, std::span<const uint8_t> payload) {
  uint8_t out[kMaxEncodedFrame];
  const size_t n = encode_frame(type, seq, payload.data(), static_cast<uint8_t>(payload.size()), out, sizeof out);
  if (n == 0 || payload.size() > kMaxPayload)
    throw LinkError(LinkErrorKind::kProtocol, fmt::format("{}: payload of {} bytes does not fit a frame",
                                                          msg_name(type), payload.size()));
  transport_.write(std::span<const uint8_t>(out, n));
}

Frame Session::request(MsgType type, std::span<const uint8_t> payload, std::optional<MsgType> data_reply_type,
                       int* attempts_used) {
  const uint8_t t = type_code(type);
  for (int attempt = 0; attempt <= opts_.retries; ++attempt) {
    if (attempts_used) *attempts_used = attempt + 1;
    const uint8_t seq = take_seq();
    send_frame(t, seq, payload);
    const auto deadline = std::chrono::steady_clock::now() + opts_.reply_timeout;
    bool busy = false;
    for (;;) {
      // Look through what has arrived for our answer; keep everything else in order.
      for (auto it = inbox_.begin(); it != inbox_.end();) {
        if (it->type == type_code(MsgType::Ack)) {
          Ack ack{};
          if (!decode_ack(it->payload.data(), static_cast<uint8_t>(it->payload.size()), ack)) {
            ++invalid_payloads_;
            it = inbox_.erase(it);
            continue;
          }
          if (ack.acked_seq == seq && ack.acked_type == t) {
            Frame f = std::move(*it);
            inbox_.erase(it);
            if (ack.status == static_cast<uint8_t>(Nack::Busy) && attempt < opts_.retries) {
              // The module is still writing EEPROM for an earlier request (typically after we
              // resent one): wait a little and try again with a new seq.
              busy = true;
              break;
            }
            if (ack.status != static_cast<uint8_t>(Nack::Ok)) throw NackError(t, ack.status, ack.detail);
            return f;
          }
        } else if (data_reply_type && it->type == type_code(*data_reply_type) && it->seq == seq) {
          Frame f = std::move(*it);
          inbox_.erase(it);
          return f;
        }
        ++it;
      }
      if (busy) break;
      // Replies to abandoned attempts and other ACKs are never useful later: drop them so the
      // inbox holds only frames a caller may still want (samples, unsolicited data).
      for (auto it = inbox_.begin(); it != inbox_.end();) {
        const bool stale_ack = it->type == type_code(MsgType::Ack);
        const bool stale_data = data_reply_type && it->type == type_code(*data_reply_type);
        if (stale_ack || stale_data) {
          ++ignored_frames_;
          it = inbox_.erase(it);
        } else {
          ++it;
        }
      }
      const auto left = std::chrono::duration_cast<Millis>(deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) break;
      pump(left);
    }
    if (busy) {
      ++busy_answers_;
      std::this_thread::sleep_for(std::min(Millis(100), opts_.reply_timeout / 4));
    }
  }
  throw LinkError(LinkErrorKind::kTimeout,
                  fmt::format("{}: no answer to {} after {} attempts of {} ms (module off, wrong port, or link too "
                              "lossy?)",
                              transport_.describe(), msg_name(t), opts_.retries + 1, opts_.reply_timeout.count()));
}

namespace {
template <class Msg>
std::vector<uint8_t> encode_payload(const Msg& m, uint8_t (*enc)(const Msg&, uint8_t*), const char* what) {
  uint8_t p[kMaxPayload];
  const uint8_t n = enc(m, p);
  if (n == 0) throw LinkError(LinkErrorKind::kProtocol, std::string(what) + ": value cannot be encoded");
  return std::vector<uint8_t>(p, p + n);
}

template <class Msg>
Msg decode_reply(const Frame& f, bool (*dec)(const uint8_t*, uint8_t, Msg&), const std::string& what) {
  Msg m{};
  if (!dec(f.payload.data(), static_cast<uint8_t>(f.payload.size()), m))
    throw LinkError(LinkErrorKind::kProtocol, what + ": malformed reply payload");
  return m;
}
}  // namespace

Info Session::get_info() {
  const Frame f = request(MsgType::GetInfo, {}, MsgType::Info);
  if (f.type == type_code(MsgType::Ack))
    throw LinkError(LinkErrorKind::kProtocol, "GET_INFO answered with a bare ACK instead of INFO");
  return decode_reply(f, decode_info, "INFO");
}

void Session::set_speed(uint16_t rpm) {
  if (!speed_value_valid(rpm))
    throw LinkError(LinkErrorKind::kProtocol,
                    fmt::format("speed {} rpm out of range (0..{}, or tach)", rpm, kMaxSpeedRpm));
  request(MsgType::SetSpeed, encode_payload(SetSpeed{rpm}, encode_set_speed, "SET_SPEED"), std::nullopt);
}

void Session::set_config(uint8_t key, int32_t value) {
  ConfigRange r{};
  if (!config_key_range(key, r))
    throw LinkError(LinkErrorKind::kProtocol, fmt::format("unknown configuration key 0x{:02x}", key));
  if (value < r.min || value > r.max)
    throw LinkError(LinkErrorKind::kProtocol, fmt::format("{} = {} out of range [{}, {}]", config_key_name(key),
                                                          value, r.min, r.max));
  request(MsgType::SetConfig, encode_payload(ConfigValue{key, value}, encode_set_config, "SET_CONFIG"),
          std::nullopt);
}

ConfigValue Session::get_config(uint8_t key) {
  const Frame f = request(MsgType::GetConfig, encode_payload(GetConfig{key}, encode_get_config, "GET_CONFIG"),
                          MsgType::Config);
  if (f.type == type_code(MsgType::Ack))
    throw LinkError(LinkErrorKind::kProtocol, "GET_CONFIG answered with a bare ACK instead of CONFIG");
  return decode_reply(f, decode_config, "CONFIG");
}

void Session::ack_alarm() { request(MsgType::AckAlarm, {}, std::nullopt); }
void Session::reboot() { request(MsgType::Reboot, {}, std::nullopt); }

AuthChallenge Session::model_begin(uint16_t total_len, uint32_t blob_crc32) {
  const Frame f = request(MsgType::ModelBegin,
                          encode_payload(ModelBegin{total_len, blob_crc32}, encode_model_begin, "MODEL_BEGIN"),
                          MsgType::AuthChallenge);
  if (f.type == type_code(MsgType::Ack))
    throw LinkError(LinkErrorKind::kProtocol, "MODEL_BEGIN answered with a bare ACK instead of AUTH_CHALLENGE");
  return decode_reply(f, decode_auth_challenge, "AUTH_CHALLENGE");
}

void Session::model_chunk(uint16_t offset, std::span<const uint8_t> data) {
  ModelChunk c{};
  c.offset = offset;
  c.len = static_cast<uint8_t>(data.size());
  if (data.size() == 0 || data.size() > kMaxModelData)
    throw LinkError(LinkErrorKind::kProtocol, "MODEL_CHUNK: 1..56 bytes per chunk");
  std::copy(data.begin(), data.end(), c.data);
  request(MsgType::ModelChunk, encode_payload(c, encode_model_chunk, "MODEL_CHUNK"), std::nullopt);
}

void Session::model_commit(const uint8_t hmac[kHmacSize]) {
  ModelCommit c{};
  std::copy(hmac, hmac + kHmacSize, c.hmac);
  request(MsgType::ModelCommit, encode_payload(c, encode_model_commit, "MODEL_COMMIT"), std::nullopt);
}

ModelData Session::model_read(uint16_t offset, uint8_t len) {
  const Frame f = request(MsgType::ModelRead, encode_payload(ModelRead{offset, len}, encode_model_read, "MODEL_READ"),
                          MsgType::ModelData);
  if (f.type == type_code(MsgType::Ack))
    throw LinkError(LinkErrorKind::kProtocol, "MODEL_READ answered with a bare ACK instead of MODEL_DATA");
  auto d = decode_reply(f, decode_model_data, "MODEL_DATA");
  if (d.offset != offset || d.len != len)
    throw LinkError(LinkErrorKind::kProtocol,
                    fmt::format("MODEL_DATA answered offset {} len {} for a read of offset {} len {}", d.offset,
                                d.len, offset, len));
  return d;
}

}  // namespace btsm::link
