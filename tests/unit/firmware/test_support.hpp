// Helpers shared by the firmware tests: a host-side protocol endpoint on the native board's UART
// and valid reduced-model blobs.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "boards/sim/native_board.hpp"
#include "common/hmac.hpp"
#include "common/model_blob.hpp"
#include "common/rtd.hpp"
#include "common/wire_frame.hpp"
#include "common/wire_messages.hpp"
#include "host/thermal/model_reference.hpp"

namespace btsm::test {

inline double pt1000_ohm(double t_c) { return rtd_resistance<double>(iec60751<double>(1000.0), t_c).value; }

// A valid three-breakpoint model blob for the module's default channel roles (ch1 rear bearing,
// ch2 housing, ch3 front bearing, ch4 ambient; ch5 modelled without a role check), with both
// early stop phases; `variant` changes the gains so two blobs differ.
inline thermal::ReducedModelF64 model_f64(double variant = 0.0) {
  thermal::ReducedModelF64 f;
  f.dt_ms = 5000;
  f.n_breakpoints = 3;
  f.ambient_channel = 3;
  f.enabled_mask = 0x1F;
  f.stop_end_s[0] = 600;
  f.stop_end_s[1] = 2400;
  const uint8_t roles[5] = {3, 4, 2, kModelRoleAmbient, kModelRoleUnchecked};
  const uint16_t speeds[3] = {0, 6000, 12000};
  for (int i = 0; i < 3; ++i) {
    f.speed_rpm[i] = speeds[i];
    for (int j = 0; j < 5; ++j) {
      if (j == 3) continue;
      f.a[i][j] = 0.998 - 0.0002 * i - 0.0001 * j;
      f.b_K[i][j] = i == 0 ? 0.0 : (0.02 * i + variant * 1e-3) * (1.0 - f.a[i][j]) * (10.0 + j);
    }
  }
  for (int j = 0; j < 5; ++j) {
    f.role[j] = roles[j];
    if (j == 3) continue;
    f.stop_a[0][j] = 0.995 - 0.001 * j;
    f.stop_a[1][j] = 0.997 - 0.0005 * j;
  }
  return f;
}

inline std::vector<uint8_t> model_blob(double variant = 0.0) {
  ReducedModel m;
  const ModelCheck c = thermal::quantize(model_f64(variant), m);
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
