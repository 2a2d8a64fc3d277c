// Helpers shared by the firmware tests: a host-side protocol endpoint on the native board's UART
// and valid reduced-model blobs.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "boards/sim/native_board.hpp"
#include "common/hmac.hpp"
#include "common/reduced_model.hpp"
#include "common/rtd.hpp"
#include "common/wire_frame.hpp"
#include "common/wire_messages.hpp"

namespace btsm::test {

inline double pt1000_ohm(double t_c) { return rtd_resistance<double>(iec60751<double>(1000.0), t_c).value; }

// A valid two-breakpoint model blob; `variant` changes the gains so two blobs differ.
inline std::vector<uint8_t> model_blob(double variant = 0.0) {
  ReducedModelF64 f;
  f.dt_ms = 5000;
  f.n_breakpoints = 3;
  f.ambient_channel = 3;
  f.enabled_mask = 0x1F;
  const uint16_t speeds[3] = {0, 6000, 12000};
  for (int i = 0; i < 3; ++i) {
    f.speed_rpm[i] = speeds[i];
    f.a[i] = 0.998 - 0.0002 * i;
    f.b[i] = i == 0 ? 0.0 : 0.004 * i + variant * 1e-3;
    for (int j = 0; j < 5; ++j) {
      f.c[i][j] = j == 3 ? 0.0 : 1.0 - 0.1 * j;
      f.d[i][j] = i == 0 || j == 3 ? 0.0 : 0.05 * j;
    }
  }
  ReducedModel m;
  const ModelCheck c = quantize(f, m);
  if (!c.ok()) return {};
  std::vector<uint8_t> blob(kReducedModelBlobSize);
  encode(m, blob.data());
  return blob;
}

// Recomputes the blob-internal CRC after a test edited the blob.
inline void fix_blob_crc(std::vector<uint8_t>& blob) {
  put_le32(blob.data() + kBlobOffCrc, crc32(blob.data(), kBlobOffCrc));
}

inline std::array<uint8_t, 32> dev_key() {
  std::array<uint8_t, 32> k{};
  for (uint8_t i = 0; i < 32; ++i) k[i] = i;
  return k;
}

struct Frame {
  uint8_t type = 0, seq = 0;
  std::vector<uint8_t> payload;
};

// Host side of the UART: sends requests, collects decoded frames from the firmware.
class HostLink {
 public:
  explicit HostLink(sim::NativeBoard& b) : board_(b) {}

  void send(wire::MsgType type, uint8_t seq, const std::vector<uint8_t>& payload) {
    std::vector<uint8_t> out(wire::kMaxEncodedFrame);
    const size_t n = wire::encode_frame(wire::type_code(type), seq, payload.data(),
                                        static_cast<uint8_t>(payload.size()), out.data(), out.size());
    out.resize(n);
    board_.host_send(out);
  }

  // Drains the UART into the frame list.
  void collect() {
    for (uint8_t b : board_.host_receive()) {
      if (dec_.push(b)) {
        Frame f;
        f.type = dec_.type();
        f.seq = dec_.seq();
        f.payload.assign(dec_.payload(), dec_.payload() + dec_.payload_len());
        frames.push_back(f);
      }
    }
  }

  // First frame of `type` (removed from the list), or nullopt.
  std::optional<Frame> take(wire::MsgType type) {
    collect();
    for (size_t i = 0; i < frames.size(); ++i) {
      if (frames[i].type == wire::type_code(type)) {
        Frame f = frames[i];
        frames.erase(frames.begin() + static_cast<long>(i));
        return f;
      }
    }
    return std::nullopt;
  }

  std::vector<Frame> frames;

 private:
  sim::NativeBoard& board_;
  wire::FrameDecoder dec_;
};

}  // namespace btsm::test
