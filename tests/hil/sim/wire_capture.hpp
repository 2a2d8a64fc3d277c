#pragma once
// Test helper: decodes the module's serial byte stream (common/wire_frame.hpp +
// wire_messages.hpp) into SAMPLE, INFO, ACK, AUTH_CHALLENGE and MODEL_DATA messages, and builds
// host -> module frames.
#include "common/wire_frame.hpp"
#include "common/wire_messages.hpp"

#include <cstdint>
#include <vector>

namespace btsm::test {

struct Capture {
  std::vector<wire::Sample> samples;
  std::vector<wire::Info> infos;
  std::vector<wire::Ack> acks;
  std::vector<wire::AuthChallenge> challenges;
  std::vector<wire::ModelData> model_data;
  uint64_t other_frames = 0;
  uint64_t undecodable = 0;
  wire::FrameDecoder decoder;

  void feed(const std::vector<uint8_t>& bytes) {
    for (uint8_t b : bytes) {
      if (!decoder.push(b)) continue;
      const uint8_t* p = decoder.payload();
      const uint8_t n = decoder.payload_len();
      bool ok = true;
      switch (decoder.type()) {
        case uint8_t(wire::MsgType::Sample): {
          wire::Sample s{};
          ok = wire::decode_sample(p, n, s);
          if (ok) samples.push_back(s);
          break;
        }
        case uint8_t(wire::MsgType::Info): {
          wire::Info s{};
          ok = wire::decode_info(p, n, s);
          if (ok) infos.push_back(s);
          break;
        }
        case uint8_t(wire::MsgType::Ack): {
          wire::Ack s{};
          ok = wire::decode_ack(p, n, s);
          if (ok) acks.push_back(s);
          break;
        }
        case uint8_t(wire::MsgType::AuthChallenge): {
          wire::AuthChallenge s{};
          ok = wire::decode_auth_challenge(p, n, s);
          if (ok) challenges.push_back(s);
          break;
        }
        case uint8_t(wire::MsgType::ModelData): {
          wire::ModelData s{};
          ok = wire::decode_model_data(p, n, s);
          if (ok) model_data.push_back(s);
          break;
        }
        default: ++other_frames;
      }
      if (!ok) ++undecodable;
    }
  }
};

// One encoded host -> module frame.
inline std::vector<uint8_t> frame(uint8_t type, uint8_t seq, const uint8_t* payload, uint8_t len) {
  std::vector<uint8_t> out;
  auto sink = [&out](uint8_t b) { out.push_back(b); };
  wire::write_frame(sink, type, seq, payload, len);
  return out;
}

}  // namespace btsm::test
