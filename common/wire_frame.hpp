// BTSM serial framing: raw frame layout, HDLC-style byte stuffing, streaming encoder and an
// incremental, resynchronising decoder. C++14 without the standard library (shared by the
// ATmega328P firmware and the host tool).
//
// Raw frame (all multi-byte fields little-endian), at most kMaxRawFrame = 64 bytes:
//   [version:1][type:1][seq:1][len:1][payload:len][crc16:2]
//   crc16 = CRC-16/CCITT-FALSE over version..payload (crc.hpp).
// On the wire every frame is sent as FLAG, stuffed raw bytes, FLAG. Stuffing replaces each of
// 0x7E (FLAG), 0x7D (ESC) and 0x2B ('+') by ESC, byte ^ 0x20. So an encoded stream contains no
// '+' at all: the Bluno's CC2540 bridge switches to AT-command mode when it sees "+++", and a
// binary frame must never be able to trigger that. The encoding is canonical: the decoder rejects
// any other escape and any unescaped '+', so every accepted frame re-encodes to the same bytes.
#ifndef BTSM_COMMON_WIRE_FRAME_HPP
#define BTSM_COMMON_WIRE_FRAME_HPP

#include <stddef.h>
#include <stdint.h>

#include "byte_order.hpp"
#include "crc.hpp"

namespace btsm {
namespace wire {

// Bumped whenever a message layout or meaning changes; the decoder drops other versions.
const uint8_t kProtocolVersion = 1;

const uint8_t kFlag = 0x7E;
const uint8_t kEsc = 0x7D;
const uint8_t kEscXor = 0x20;
const uint8_t kAtModeChar = 0x2B;  // '+', escaped so "+++" can never appear on the wire

const uint8_t kHeaderSize = 4;  // version, type, seq, len
const uint8_t kCrcSize = 2;
const uint8_t kMaxRawFrame = 64;
const uint8_t kMaxPayload = kMaxRawFrame - kHeaderSize - kCrcSize;  // 58
const uint8_t kMinRawFrame = kHeaderSize + kCrcSize;                // 6, empty payload
// Worst case on the wire: two flags plus every raw byte escaped.
const uint8_t kMaxEncodedFrame = 2 + 2 * kMaxRawFrame;  // 130
// Default LE ATT MTU 23 leaves 20 bytes per BLE write/notification.
const uint8_t kBleWriteSize = 20;

// True for bytes that must be sent as ESC, byte ^ 0x20.
inline bool needs_escape(uint8_t b) { return b == kFlag || b == kEsc || b == kAtModeChar; }

// Number of wire bytes one raw byte occupies.
inline uint8_t stuffed_size(uint8_t b) { return needs_escape(b) ? 2 : 1; }

// ---------------------------------------------------------------------------------------------
// Encoder. A Sink is anything callable as sink(uint8_t) (a lambda on the host, a small struct
// with operator() that feeds the UART on the MCU), so no frame-sized buffer is needed.

template <class Sink>
inline void put_stuffed(Sink& sink, uint8_t b) {
  if (needs_escape(b)) {
    sink(kEsc);
    sink(static_cast<uint8_t>(b ^ kEscXor));
  } else {
    sink(b);
  }
}

// Writes FLAG, the stuffed bytes raw[0..n), FLAG. raw must already contain header and CRC
// (see build_raw_frame). Used directly by tests to send deliberately malformed frames.
template <class Sink>
inline void write_stuffed(Sink& sink, const uint8_t* raw, size_t n) {
  sink(kFlag);
  for (size_t i = 0; i < n; ++i) put_stuffed(sink, raw[i]);
  sink(kFlag);
}

// Streams one complete frame (current protocol version) to sink, computing the CRC on the fly.
// Returns false and writes nothing if len > kMaxPayload (or payload is null with len > 0).
template <class Sink>
inline bool write_frame(Sink& sink, uint8_t type, uint8_t seq, const uint8_t* payload,
                        uint8_t len) {
  if (len > kMaxPayload || (len > 0 && payload == nullptr)) return false;
  const uint8_t header[kHeaderSize] = {kProtocolVersion, type, seq, len};
  uint16_t crc = crc16_ccitt(header, kHeaderSize);
  crc = crc16_ccitt(payload, len, crc);
  sink(kFlag);
  for (uint8_t i = 0; i < kHeaderSize; ++i) put_stuffed(sink, header[i]);
  for (uint8_t i = 0; i < len; ++i) put_stuffed(sink, payload[i]);
  put_stuffed(sink, static_cast<uint8_t>(crc));
  put_stuffed(sink, static_cast<uint8_t>(crc >> 8));
  sink(kFlag);
  return true;
}

// Raw-buffer encoder (the MCU's): the message encoder writes the payload straight into
// raw + kHeaderSize of a kMaxRawFrame buffer, seal_raw_frame() adds the header and the CRC in
// place (one tight CRC pass), and resume_stuffed() streams FLAG, the stuffed raw bytes, FLAG into
// a sink that may refuse bytes (the UART ring), continuing where it stopped on the next call:
//   n = seal_raw_frame(raw, type, seq, len); StuffCursor c; start_stuffed(c);
//   until resume_stuffed(put, c, raw, n) returns true   (raw unchanged meanwhile)
// Same wire bytes as write_frame; per byte a load, the escape test and the sink call (on the AVR
// ~26 cycles a byte into the UART ring's claimed space, against ~77 for an encoder that builds
// each byte and its CRC on the fly).
namespace detail {
// Header and CRC around a payload already at raw + kHeaderSize (len <= kMaxPayload).
inline uint8_t seal(uint8_t* raw, uint8_t version, uint8_t type, uint8_t seq, uint8_t len) {
  raw[0] = version;
  raw[1] = type;
  raw[2] = seq;
  raw[3] = len;
  const uint8_t body = static_cast<uint8_t>(kHeaderSize + len);
  put_le16(raw + body, crc16_ccitt(raw, body));
  return static_cast<uint8_t>(body + kCrcSize);
}
}  // namespace detail

// Returns the raw size (header + len + CRC), or 0 if len > kMaxPayload.
inline uint8_t seal_raw_frame(uint8_t* raw, uint8_t type, uint8_t seq, uint8_t len) {
  if (len > kMaxPayload) return 0;
  return detail::seal(raw, kProtocolVersion, type, seq, len);
}

struct StuffCursor {
  uint8_t pos;   // 0 = opening flag, 1..n = raw byte pos - 1, n + 1 = closing flag
  bool escaped;  // the ESC of raw byte pos - 1 is already out, its second byte is not
};

inline void start_stuffed(StuffCursor& c) {
  c.pos = 0;
  c.escaped = false;
}

// Returns true once the closing flag is out.
template <class Put>
inline bool resume_stuffed(Put& put, StuffCursor& c, const uint8_t* raw, uint8_t n) {
  uint8_t pos = c.pos;
  bool escaped = c.escaped;
  bool done = false;
  if (pos == 0) {
    if (!put(kFlag)) return false;
    pos = 1;
  }
  for (;;) {
    if (pos > n) {
      done = put(kFlag);
      if (done) ++pos;
      break;
    }
    uint8_t b = raw[pos - 1];
    if (needs_escape(b)) {
      if (!escaped) {
        if (!put(kEsc)) break;
        escaped = true;
      }
      b = static_cast<uint8_t>(b ^ kEscXor);
    }
    if (!put(b)) break;
    escaped = false;
    ++pos;
  }
  c.pos = pos;
  c.escaped = escaped;
  return done;
}

// Builds the raw (unstuffed) frame with an explicit version into raw (>= kMaxRawFrame bytes).
// Returns the raw size, or 0 if len > kMaxPayload.
inline size_t build_raw_frame(uint8_t version, uint8_t type, uint8_t seq, const uint8_t* payload,
                              uint8_t len, uint8_t* raw) {
  if (len > kMaxPayload || (len > 0 && payload == nullptr)) return 0;
  for (uint8_t i = 0; i < len; ++i) raw[kHeaderSize + i] = payload[i];
  return detail::seal(raw, version, type, seq, len);
}

// Sink that fills a caller buffer and remembers whether it ran out of room.
struct BufferSink {
  uint8_t* out;
  size_t capacity;
  size_t size;
  bool overflow;
  BufferSink(uint8_t* o, size_t cap) : out(o), capacity(cap), size(0), overflow(false) {}
  void operator()(uint8_t b) {
    if (size < capacity) {
      out[size++] = b;
    } else {
      overflow = true;
    }
  }
};

// Sink that only counts bytes (exact encoded size without a buffer).
struct CountingSink {
  size_t size;
  CountingSink() : size(0) {}
  void operator()(uint8_t) { ++size; }
};

// Encodes one frame into out[0..capacity). Returns the number of wire bytes (flags included), or
// 0 if len > kMaxPayload or the frame does not fit (kMaxEncodedFrame always suffices).
inline size_t encode_frame(uint8_t type, uint8_t seq, const uint8_t* payload, uint8_t len,
                           uint8_t* out, size_t capacity) {
  BufferSink sink(out, capacity);
  if (!write_frame(sink, type, seq, payload, len) || sink.overflow) return 0;
  return sink.size;
}

// Exact number of wire bytes encode_frame would produce (0 if len > kMaxPayload).
inline size_t encoded_frame_size(uint8_t type, uint8_t seq, const uint8_t* payload,
                                 uint8_t len) {
  CountingSink sink;
  if (!write_frame(sink, type, seq, payload, len)) return 0;
  return sink.size;
}

// ---------------------------------------------------------------------------------------------
// Decoder.

// Why a frame (or bytes) were dropped. One counter per kind in FrameCounters.
enum class FrameError : uint8_t {
  None = 0,
  Runt = 1,        // fewer than kMinRawFrame bytes between two flags
  TooLong = 2,     // more than kMaxRawFrame raw bytes before a flag (rest discarded)
  BadEscape = 3,   // ESC not followed by an escaped 0x7E/0x7D/0x2B, or an unescaped '+'
  BadCrc = 4,      // CRC-16 mismatch
  BadLength = 5,   // CRC fine but the len field disagrees with the received size
  BadVersion = 6,  // intact frame of another protocol version
};

inline const char* frame_error_name(FrameError e) {
  switch (e) {
    case FrameError::None: return "none";
    case FrameError::Runt: return "runt frame";
    case FrameError::TooLong: return "frame too long";
    case FrameError::BadEscape: return "bad escape";
    case FrameError::BadCrc: return "bad CRC";
    case FrameError::BadLength: return "length mismatch";
    case FrameError::BadVersion: return "wrong protocol version";
  }
  return "unknown";
}

// Saturating 16-bit counters (they stop at 65535 instead of wrapping to a misleading 0).
struct FrameCounters {
  uint16_t frames_ok;
  uint16_t runt;
  uint16_t too_long;
  uint16_t bad_escape;
  uint16_t bad_crc;
  uint16_t bad_length;
  uint16_t bad_version;
  uint16_t discarded_bytes;  // bytes skipped while hunting for a flag

  // Total rejected frames (all kinds), saturating.
  uint16_t frame_errors() const {
    const uint32_t sum = static_cast<uint32_t>(runt) + too_long + bad_escape + bad_crc +
                         bad_length + bad_version;
    return sum > 0xFFFFu ? static_cast<uint16_t>(0xFFFFu) : static_cast<uint16_t>(sum);
  }
};

inline void saturating_increment(uint16_t& c) {
  if (c != 0xFFFFu) ++c;
}

// Incremental frame decoder with a fixed kMaxRawFrame buffer (about 85 bytes of RAM).
// Feed every received byte to push(). When push() returns true a validated frame (CRC, length,
// version checked) is available through the accessors until the next push(). After garbage,
// truncation, bit flips or an over-long frame it resynchronises at the next FLAG; a closing FLAG
// also opens the next frame, so back-to-back frames may share one flag.
class FrameDecoder {
 public:
  FrameDecoder() { reset_all(); }

  // Drops any partial frame and hunts for the next flag. Counters are kept.
  void reset() {
    state_ = kHunt;
    count_ = 0;
    last_error_ = FrameError::None;
  }

  // reset() plus zeroed counters.
  void reset_all() {
    reset();
    counters_ = FrameCounters();
  }

  bool push(uint8_t b) {
    if (b == kFlag) return on_flag();
    switch (state_) {
      case kHunt:
        saturating_increment(counters_.discarded_bytes);
        return false;
      case kEscaped: {
        const uint8_t raw = static_cast<uint8_t>(b ^ kEscXor);
        if (!needs_escape(raw)) return fail(FrameError::BadEscape);
        state_ = kInFrame;
        return store(raw);
      }
      default:  // kInFrame
        if (b == kEsc) {
          state_ = kEscaped;
          return false;
        }
        if (b == kAtModeChar) return fail(FrameError::BadEscape);
        return store(b);
    }
  }

  uint8_t version() const { return buf_[0]; }
  uint8_t type() const { return buf_[1]; }
  uint8_t seq() const { return buf_[2]; }
  uint8_t payload_len() const { return buf_[3]; }
  const uint8_t* payload() const { return buf_ + kHeaderSize; }
  // Raw frame (header, payload, CRC) of the last accepted frame.
  const uint8_t* raw() const { return buf_; }
  uint8_t raw_size() const { return static_cast<uint8_t>(kMinRawFrame + buf_[3]); }

  // Cause of the most recent rejection (None after an accepted frame).
  FrameError last_error() const { return last_error_; }
  const FrameCounters& counters() const { return counters_; }

 private:
  enum State : uint8_t { kHunt, kInFrame, kEscaped };

  bool store(uint8_t raw) {
    if (count_ >= kMaxRawFrame) return fail(FrameError::TooLong);
    buf_[count_++] = raw;
    return false;
  }

  // Counts the error and discards everything up to the next flag.
  bool fail(FrameError e) {
    count(e);
    state_ = kHunt;
    count_ = 0;
    return false;
  }

  void count(FrameError e) {
    last_error_ = e;
    switch (e) {
      case FrameError::Runt: saturating_increment(counters_.runt); break;
      case FrameError::TooLong: saturating_increment(counters_.too_long); break;
      case FrameError::BadEscape: saturating_increment(counters_.bad_escape); break;
      case FrameError::BadCrc: saturating_increment(counters_.bad_crc); break;
      case FrameError::BadLength: saturating_increment(counters_.bad_length); break;
      case FrameError::BadVersion: saturating_increment(counters_.bad_version); break;
      case FrameError::None: break;
    }
  }

  bool on_flag() {
    const State was = static_cast<State>(state_);
    const uint8_t n = count_;
    state_ = kInFrame;  // this flag opens the next frame whatever happened before
    count_ = 0;
    if (was == kHunt) return false;
    if (was == kEscaped) {  // ESC FLAG: sender aborted the frame
      count(FrameError::BadEscape);
      return false;
    }
    if (n == 0) return false;  // idle flags between frames
    if (n < kMinRawFrame) {
      count(FrameError::Runt);
      return false;
    }
    const uint8_t body = static_cast<uint8_t>(n - kCrcSize);
    if (crc16_ccitt(buf_, body) != get_le16(buf_ + body)) {
      count(FrameError::BadCrc);
      return false;
    }
    if (buf_[3] != body - kHeaderSize) {
      count(FrameError::BadLength);
      return false;
    }
    if (buf_[0] != kProtocolVersion) {
      count(FrameError::BadVersion);
      return false;
    }
    last_error_ = FrameError::None;
    saturating_increment(counters_.frames_ok);
    return true;
  }

  uint8_t buf_[kMaxRawFrame];
  uint8_t count_;
  uint8_t state_;
  FrameError last_error_;
  FrameCounters counters_;
};

}  // namespace wire
}  // namespace btsm

#endif  // BTSM_COMMON_WIRE_FRAME_HPP
