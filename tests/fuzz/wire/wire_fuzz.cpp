// libFuzzer target for the wire protocol (frame decoder + message codecs).
//
// Properties checked on every input (abort() = finding):
//  1. Stream path: the input is fed byte by byte to a FrameDecoder. Every accepted frame
//     re-encodes to exactly the bytes it arrived as (flag to flag): the encoding is canonical,
//     so a frame can only be accepted if it is what an honest encoder would have sent.
//     Its payload, if its type is known and it decodes, re-encodes to identical bytes.
//  2. Frame path: data[0] = type, data[1] = seq, the rest (up to 58 bytes) = payload. The encoded
//     frame never contains '+', has the predicted size, and a fresh decoder accepts it exactly
//     once, on the last byte, unchanged. The payload then goes through the message codecs.
//  3. Corruption path: data[0..1] = type, seq; data[2..4] = one fault (op, position, value);
//     the rest = payload. The valid frame gets exactly that one fault, then goes through a
//     decoder. Always: anything accepted is canonical (as in 1). Guaranteed by construction, so
//     asserted: a substituted byte that is neither FLAG nor ESC before or after (one raw byte
//     changed, a burst <= 8 bits that CRC-16 always detects) is rejected; an escape pair written
//     as the plain byte, or a plain byte needlessly escaped (same raw content, non-canonical
//     encoding), is rejected. Faults that create flags or shift bytes are only checked for
//     canonicity: a fragment passing a 16-bit CRC by chance is a limit of the CRC, not a bug.
//  4. MODEL_CHUNK sizing: model_chunk_fit() on the input yields a chunk whose encoded frame fits
//     one 20-byte BLE write, and one more byte would not fit.
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/wire_frame.hpp"
#include "common/wire_messages.hpp"

using namespace btsm::wire;

#define FUZZ_CHECK(cond)                                                   \
  do {                                                                     \
    if (!(cond)) {                                                         \
      fprintf(stderr, "wire_fuzz: check failed: %s (line %d)\n", #cond, __LINE__); \
      abort();                                                             \
    }                                                                      \
  } while (0)

namespace {

template <class Msg>
void check_codec(const uint8_t* p, uint8_t len, bool (*dec)(const uint8_t*, uint8_t, Msg&),
                 uint8_t (*enc)(const Msg&, uint8_t*)) {
  Msg m;
  memset(&m, 0xA5, sizeof m);  // decode must not depend on prior contents
  if (!dec(p, len, m)) return;
  uint8_t again[kMaxPayload];
  const uint8_t n = enc(m, again);
  FUZZ_CHECK(n == len);
  FUZZ_CHECK(memcmp(again, p, len) == 0);
}

void check_message(uint8_t type, const uint8_t* p, uint8_t len) {
  uint8_t min_len = 0, max_len = 0;
  const bool known = payload_length_range(type, min_len, max_len);
  FUZZ_CHECK(known == (msg_type_name(type) != nullptr));
  if (!known) return;
  FUZZ_CHECK(max_len <= kMaxPayload);
  const bool len_ok = len >= min_len && len <= max_len;
  switch (static_cast<MsgType>(type)) {
    case MsgType::Sample: check_codec(p, len, decode_sample, encode_sample); break;
    case MsgType::Info: check_codec(p, len, decode_info, encode_info); break;
    case MsgType::Ack: check_codec(p, len, decode_ack, encode_ack); break;
    case MsgType::AuthChallenge:
      check_codec(p, len, decode_auth_challenge, encode_auth_challenge);
      break;
    case MsgType::ModelData: check_codec(p, len, decode_model_data, encode_model_data); break;
    case MsgType::ModelChunk: check_codec(p, len, decode_model_chunk, encode_model_chunk); break;
    case MsgType::Config: check_codec(p, len, decode_config, encode_config); break;
    case MsgType::SetConfig: check_codec(p, len, decode_set_config, encode_set_config); break;
    case MsgType::SetSpeed: check_codec(p, len, decode_set_speed, encode_set_speed); break;
    case MsgType::ModelBegin: check_codec(p, len, decode_model_begin, encode_model_begin); break;
    case MsgType::ModelCommit:
      check_codec(p, len, decode_model_commit, encode_model_commit);
      break;
    case MsgType::ModelAuth: check_codec(p, len, decode_model_auth, encode_model_auth); break;
    case MsgType::ModelRead: check_codec(p, len, decode_model_read, encode_model_read); break;
    case MsgType::GetConfig: check_codec(p, len, decode_get_config, encode_get_config); break;
    case MsgType::GetInfo:
    case MsgType::AckAlarm:
    case MsgType::Reboot: FUZZ_CHECK(decode_empty(len) == len_ok); break;
  }
  // Every message with a fixed length must refuse all other lengths; spot-check len itself.
  if (!len_ok) {
    // Decoders were already run above; a decode success with a bad length would have been
    // caught by the re-encode length check (encoders only produce valid lengths).
  }
}

void stream_path(const uint8_t* data, size_t size) {
  FrameDecoder d;
  size_t last_flag = static_cast<size_t>(-1);
  uint32_t accepted = 0;
  for (size_t i = 0; i < size; ++i) {
    const uint8_t b = data[i];
    if (d.push(b)) {
      ++accepted;
      FUZZ_CHECK(b == kFlag);
      FUZZ_CHECK(last_flag != static_cast<size_t>(-1));
      FUZZ_CHECK(d.version() == kProtocolVersion);
      FUZZ_CHECK(d.payload_len() <= kMaxPayload);
      FUZZ_CHECK(d.last_error() == FrameError::None);
      uint8_t out[kMaxEncodedFrame];
      const size_t n =
          encode_frame(d.type(), d.seq(), d.payload(), d.payload_len(), out, sizeof out);
      FUZZ_CHECK(n == i - last_flag + 1);
      FUZZ_CHECK(memcmp(out, data + last_flag, n) == 0);
      check_message(d.type(), d.payload(), d.payload_len());
    }
    if (b == kFlag) last_flag = i;
  }
  if (accepted < 0xFFFF) FUZZ_CHECK(d.counters().frames_ok == accepted);
}

void frame_path(const uint8_t* data, size_t size) {
  if (size < 2) return;
  const uint8_t type = data[0];
  const uint8_t seq = data[1];
  const uint8_t len = static_cast<uint8_t>(size - 2 > kMaxPayload ? kMaxPayload : size - 2);
  const uint8_t* payload = data + 2;
  uint8_t wire[kMaxEncodedFrame];
  const size_t n = encode_frame(type, seq, payload, len, wire, sizeof wire);
  FUZZ_CHECK(n >= 2u + kMinRawFrame && n <= kMaxEncodedFrame);
  FUZZ_CHECK(n == encoded_frame_size(type, seq, payload, len));
  for (size_t i = 0; i < n; ++i) FUZZ_CHECK(wire[i] != kAtModeChar);
  FrameDecoder d;
  for (size_t i = 0; i < n; ++i) {
    const bool accepted = d.push(wire[i]);
    FUZZ_CHECK(accepted == (i == n - 1));
  }
  FUZZ_CHECK(d.type() == type && d.seq() == seq && d.payload_len() == len);
  FUZZ_CHECK(memcmp(d.payload(), payload, len) == 0);
  FUZZ_CHECK(d.counters().frame_errors() == 0);
  check_message(type, payload, len);
}

// Feeds wire[0..n) to a fresh decoder; checks canonicity of every accepted frame; returns the
// number accepted.
uint32_t decode_checked(const uint8_t* wire, size_t n) {
  FrameDecoder d;
  size_t last_flag = static_cast<size_t>(-1);
  uint32_t accepted = 0;
  for (size_t i = 0; i < n; ++i) {
    if (d.push(wire[i])) {
      ++accepted;
      FUZZ_CHECK(last_flag != static_cast<size_t>(-1));
      uint8_t out[kMaxEncodedFrame];
      const size_t m =
          encode_frame(d.type(), d.seq(), d.payload(), d.payload_len(), out, sizeof out);
      FUZZ_CHECK(m == i - last_flag + 1);
      FUZZ_CHECK(memcmp(out, wire + last_flag, m) == 0);
    }
    if (wire[i] == kFlag) last_flag = i;
  }
  return accepted;
}

void corruption_path(const uint8_t* data, size_t size) {
  if (size < 5) return;
  const uint8_t type = data[0];
  const uint8_t seq = data[1];
  const uint8_t op = data[2] % 6;
  const uint8_t pos_in = data[3];
  const uint8_t val = data[4];
  const uint8_t len = static_cast<uint8_t>(size - 5 > kMaxPayload ? kMaxPayload : size - 5);
  uint8_t wire[kMaxEncodedFrame + 2];
  size_t n = encode_frame(type, seq, data + 5, len, wire, kMaxEncodedFrame);
  FUZZ_CHECK(n > 0);
  // Positions strictly inside the flags.
  const size_t pos = 1 + pos_in % (n - 2);
  bool must_reject = false;
  switch (op) {
    case 0:  // flip one bit
    case 1: {  // substitute one byte
      const uint8_t old = wire[pos];
      const uint8_t now = op == 0 ? static_cast<uint8_t>(old ^ (1u << (val & 7))) : val;
      if (now == old) return;
      wire[pos] = now;
      must_reject = old != kFlag && old != kEsc && now != kFlag && now != kEsc;
      break;
    }
    case 2: {  // write the pos-th escape pair (cyclically) as the plain reserved byte
      size_t k = pos;
      size_t tries = 0;
      while (wire[k] != kEsc && tries < n) {
        k = 1 + (k % (n - 2));
        ++tries;
      }
      if (wire[k] != kEsc) return;
      wire[k] = static_cast<uint8_t>(wire[k + 1] ^ kEscXor);
      memmove(wire + k + 1, wire + k + 2, n - k - 2);
      --n;
      must_reject = true;
      break;
    }
    case 3: {  // escape a byte that needs no escaping
      if (wire[pos] == kEsc || wire[pos - 1] == kEsc) return;
      memmove(wire + pos + 1, wire + pos, n - pos);
      wire[pos + 1] = static_cast<uint8_t>(wire[pos] ^ kEscXor);
      wire[pos] = kEsc;
      ++n;
      must_reject = true;
      break;
    }
    case 4:  // delete one byte
      memmove(wire + pos, wire + pos + 1, n - pos - 1);
      --n;
      break;
    default:  // insert one byte
      memmove(wire + pos + 1, wire + pos, n - pos);
      wire[pos] = val;
      ++n;
      break;
  }
  const uint32_t accepted = decode_checked(wire, n);
  if (must_reject) FUZZ_CHECK(accepted == 0);
}

void chunk_path(const uint8_t* data, size_t size) {
  if (size < 3) return;
  const uint8_t seq = data[0];
  const uint16_t offset = static_cast<uint16_t>(data[1] | (data[2] << 8)) % kMaxModelBlobSize;
  const uint8_t* blob = data + 3;
  size_t avail = size - 3;
  if (offset + avail > kMaxModelBlobSize) avail = kMaxModelBlobSize - offset;
  const uint8_t n = model_chunk_fit(seq, offset, blob, avail);
  if (avail == 0) {
    FUZZ_CHECK(n == 0);
    return;
  }
  FUZZ_CHECK(n >= 1 && n <= avail);
  ModelChunk c;
  c.offset = offset;
  c.len = n;
  memcpy(c.data, blob, n);
  uint8_t wire[kMaxEncodedFrame];
  const size_t size_n =
      encode_message_frame(MsgType::ModelChunk, seq, c, encode_model_chunk, wire, sizeof wire);
  FUZZ_CHECK(size_n > 0 && size_n <= kBleWriteSize);
  if (n < avail && n < kMaxModelData) {
    c.len = static_cast<uint8_t>(n + 1);
    memcpy(c.data, blob, n + 1u);
    const size_t bigger =
        encode_message_frame(MsgType::ModelChunk, seq, c, encode_model_chunk, wire, sizeof wire);
    FUZZ_CHECK(bigger == 0 || bigger > kBleWriteSize);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  stream_path(data, size);
  frame_path(data, size);
  corruption_path(data, size);
  chunk_path(data, size);
  return 0;
}
