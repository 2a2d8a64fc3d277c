#pragma once
// The "scheduled_model" table of a reduced-model JSON read back and checked against the blob
// `btsm reduce` wrote beside it ("blob_hex"). Why: flash-model sends the blob, never the table, so
// a hand edit of the table (a raised abs_limit_c, a gain, another node) would reach the module as
// the blob's old value without a word. The table is re-encoded with the quantizer reduce used and
// compared with the blob byte for byte; the first field that differs is named by its path.
#include "model_reference.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <span>
#include <string>

namespace btsm::thermal {

// The model a "scheduled_model" object describes, in the units reduce wrote it (the inverse of
// reduction_to_json's table). Throws std::invalid_argument naming the field by its path in the
// table ("breakpoints[1].b_K[0] is \"x\", not a number") when one is missing or malformed.
ReducedModelF64 scheduled_model_from_json(const nlohmann::json& sm);

// "" when `sm` describes exactly the model of `blob` (a valid blob: decode() ok; an invalid one is
// check_model_blob's to name), else why not, a sentence for "FILE: <why>" naming the first field
// that differs (by its path in the table), both values and what to do. `blob_key` names where the
// blob came from ("\"blob_hex\"").
std::string scheduled_model_contradiction(const nlohmann::json& sm, std::span<const uint8_t> blob,
                                          const std::string& blob_key = "\"blob_hex\"");

}  // namespace btsm::thermal
