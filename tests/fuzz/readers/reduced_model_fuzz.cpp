// The input of `btsm flash-model`: a raw blob or the reduced-model JSON holding it (blob_hex, or
// blob_file resolved through a stub that returns fixed bytes -- no file system access). Any input
// gives bytes or throws io::InputError; then the local blob check (the firmware's rules) runs on
// them. Property: a blob the check accepts decodes and re-encodes to the same 464 bytes (the
// format has no byte the check ignores).
#include "common/model_blob.hpp"
#include "fuzz_check.hpp"
#include "host/io/hex.hpp"
#include "host/io/input_error.hpp"
#include "host/link/model_blob_file.hpp"

#include <string>

using namespace btsm;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  // First byte: read as a .json file or as a raw .bin.
  const bool as_json = data[0] & 1;
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  const std::string path = as_json ? "/fuzz/reduced.json" : "/fuzz/model.bin";
  std::vector<uint8_t> blob;
  try {
    blob = link::model_blob_from_content(text, path, [&](const std::string& p) {
      FUZZ_CHECK(!p.empty());
      return std::vector<uint8_t>(text.begin(), text.end());
    });
  } catch (const io::InputError&) {
    return 0;
  }
  const std::string why = link::check_model_blob(blob);
  if (why.empty()) {
    ReducedModel m;
    FUZZ_CHECK(decode(blob.data(), blob.size(), m).ok());
    std::vector<uint8_t> again(kReducedModelBlobSize);
    encode(m, again.data());
    FUZZ_CHECK(again == blob);
  }
  return 0;
}
