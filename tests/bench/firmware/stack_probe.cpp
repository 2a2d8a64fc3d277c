// Stack-depth bench (`bench_stack`, part of the `bench` target): runs the real AVR image in simavr with
// the development key patched into .btsm_key, performs GET_INFO, a full authenticated model
// upload and a REBOOT over the UART, and reports the deepest stack use (SRAM painted with 0xA5
// before start). No AD7794 is attached (the firmware reports ADC faults), which does not change
// the deepest paths (MODEL_BEGIN hashing, MODEL_COMMIT validation, boot with a stored model).
// Usage: stack_probe IMAGE.elf. The end of .bss comes from the image (0x100 + .data + .bss); the
// margin is what no path touched between it and the deepest stack write.
#include <simavr/sim_avr.h>
#include <simavr/sim_elf.h>
#include <simavr/avr_uart.h>
#include <simavr/avr_ioport.h>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <vector>
#include "common/hmac.hpp"
#include "common/wire_frame.hpp"
#include "common/wire_messages.hpp"
#include "common/device_key.hpp"
#include "tests/bench/firmware/stack_paint.hpp"
#include "tests/unit/firmware/test_support.hpp"  // model_blob()

static std::vector<uint8_t> out_bytes;
static void uart_out(avr_irq_t*, uint32_t v, void*) { out_bytes.push_back(uint8_t(v)); }
static void no_sleep(avr_t*, avr_cycle_count_t) {}

int main(int argc, char** argv) {
  elf_firmware_t fw{};
  if (argc < 2 || elf_read_firmware(argv[1], &fw)) {
    std::fprintf(stderr, "usage: stack_probe IMAGE.elf (could not read '%s')\n", argc > 1 ? argv[1] : "");
    return 2;
  }
  const int bss_end_addr = 0x100 + static_cast<int>(fw.datasize + fw.bsssize);
  avr_t* avr = avr_make_mcu_by_name("atmega328p");
  avr_init(avr);
  avr->frequency = 16000000;
  avr_load_firmware(avr, &fw);
  avr->sleep = no_sleep;
  uint8_t rec[64], key[32];
  for (int i = 0; i < 32; ++i) key[i] = i;
  btsm::device_key::build_record(rec, 0xDE70, key);
  memcpy(avr->flash + btsm::device_key::kFlashAddress, rec, 64);
  btsm::bench::paint_sram(avr, 0x100, btsm::bench::kRamEnd + 1);
  uint32_t f = 0;
  avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &f);
  f &= ~AVR_UART_FLAG_STDIO;
  avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &f);
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), uart_out, nullptr);
  avr_irq_t* in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
  std::deque<uint8_t> to_send;
  btsm::wire::FrameDecoder dec;
  size_t consumed = 0;
  auto run_ms = [&](double ms) {
    const avr_cycle_count_t end = avr->cycle + avr_cycle_count_t(ms * 16000);
    avr_cycle_count_t next_byte = avr->cycle;
    while (avr->cycle < end) {
      if (!to_send.empty() && avr->cycle >= next_byte) {
        avr_raise_irq(in, to_send.front());
        to_send.pop_front();
        next_byte = avr->cycle + 2000;
      }
      int st = avr_run(avr);
      if (st == cpu_Done || st == cpu_Crashed) { printf("cpu state %d\n", st); return false; }
    }
    return true;
  };
  auto send = [&](btsm::wire::MsgType t, uint8_t seq, const std::vector<uint8_t>& p) {
    uint8_t buf[200];
    size_t n = btsm::wire::encode_frame(btsm::wire::type_code(t), seq, p.data(), uint8_t(p.size()), buf, sizeof buf);
    to_send.insert(to_send.end(), buf, buf + n);
  };
  auto wait_frame = [&](uint8_t type, std::vector<uint8_t>& payload) {
    for (int k = 0; k < 400; ++k) {
      run_ms(5);
      while (consumed < out_bytes.size()) {
        if (dec.push(out_bytes[consumed++]) && (dec.type() == type || dec.type() == 0x03)) {
          payload.assign(dec.payload(), dec.payload() + dec.payload_len());
          if (dec.type() == type) return true;
          if (type == 0x03) return true;
          printf("got ACK status %d instead of 0x%02x\n", payload[2], type);
          return false;
        }
      }
    }
    return false;
  };
  run_ms(200);
  std::vector<uint8_t> p;
  send(btsm::wire::MsgType::GetInfo, 1, {});
  printf("INFO: %d\n", wait_frame(0x02, p));
  auto depth = [&](const char* what) {
    printf("%s: max stack use %d bytes\n", what, btsm::bench::stack_depth(avr, bss_end_addr).max_use);
  };
  depth("before upload");
  auto blob = btsm::test::model_blob();
  std::vector<uint8_t> b(6);
  btsm::put_le16(b.data(), uint16_t(blob.size()));
  btsm::put_le32(b.data() + 2, btsm::crc32(blob.data(), blob.size()));
  send(btsm::wire::MsgType::ModelBegin, 2, b);
  std::vector<uint8_t> nonce;
  printf("CHALLENGE: %d\n", wait_frame(0x04, nonce));
  depth("after MODEL_BEGIN");
  {
    uint8_t context[btsm::wire::kModelAuthContextSize];
    btsm::wire::encode_model_auth_context(uint16_t(blob.size()), btsm::crc32(blob.data(), blob.size()), context);
    btsm::HmacSha256 auth(key, 32);
    auth.update(nonce.data(), 16);
    auth.update(context, sizeof context);
    std::vector<uint8_t> auth_tag(32);
    auth.final(auth_tag.data());
    send(btsm::wire::MsgType::ModelAuth, 3, auth_tag);
    printf("MODEL_AUTH ACK: %d status %d\n", wait_frame(0x03, p), p.size() > 2 ? p[2] : -1);
  }
  depth("after MODEL_AUTH");
  uint8_t seq = 4;
  for (size_t off = 0; off < blob.size();) {
    uint8_t n = btsm::wire::model_chunk_fit(seq, uint16_t(off), blob.data() + off, blob.size() - off);
    std::vector<uint8_t> c(2 + n);
    btsm::put_le16(c.data(), uint16_t(off));
    memcpy(c.data() + 2, blob.data() + off, n);
    send(btsm::wire::MsgType::ModelChunk, seq++, c);
    if (!wait_frame(0x03, p) || p[2] != 0) { printf("chunk at %zu failed\n", off); break; }
    off += n;
  }
  btsm::HmacSha256 mac(key, 32);
  mac.update(nonce.data(), 16);
  mac.update(blob.data(), blob.size());
  std::vector<uint8_t> tag(32);
  mac.final(tag.data());
  send(btsm::wire::MsgType::ModelCommit, seq++, tag);
  depth("after chunks");
  printf("COMMIT ACK: %d status %d\n", wait_frame(0x03, p), p.size() > 2 ? p[2] : -1);
  depth("after commit");
  run_ms(12000);  // model init after the next sweeps
  send(btsm::wire::MsgType::GetInfo, seq++, {});
  wait_frame(0x02, p);
  btsm::wire::Info info;
  btsm::wire::decode_info(p.data(), uint8_t(p.size()), info);
  printf("model_seq %u state %u samples-bytes %zu\n", info.model_seq, info.model_state, out_bytes.size());
  {
    // Repaint the free region and reboot: measures boot with a stored model (load + validate).
    btsm::bench::paint_sram(avr, bss_end_addr, btsm::bench::stack_pointer(avr) - 4);
    send(btsm::wire::MsgType::Reboot, seq++, {});
    wait_frame(0x03, p);
    run_ms(12000);
    depth("reboot with a stored model + 12 s of sweeps");
    send(btsm::wire::MsgType::GetInfo, seq++, {});
    wait_frame(0x02, p);
    btsm::wire::decode_info(p.data(), uint8_t(p.size()), info);
    printf("after reboot: model_seq %u state %u resets %u\n", info.model_seq, info.model_state, info.resets);
  }
  const btsm::bench::StackDepth d = btsm::bench::stack_depth(avr, bss_end_addr);
  printf("end of .bss 0x%x, deepest stack write 0x%x: max stack use %d bytes, untouched margin %d bytes "
         "(target >= 64: %s)\n",
         bss_end_addr, d.deepest_write, d.max_use, d.margin, d.margin >= 64 ? "met" : "NOT met");
  return 0;
}
