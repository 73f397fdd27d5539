#pragma once
// Base64 (RFC 4648, with padding): grid-tile cells travel to the page as base64 text in
// JSON, and the browser test reads the DevTools' base64 screenshots.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace anchormap::viewer {

std::string Base64Encode(const uint8_t* data, size_t size);
// nullopt for text that is not padded base64 (whitespace is not skipped).
std::optional<std::vector<uint8_t>> Base64Decode(std::string_view text);

}  // namespace anchormap::viewer
