#include "common/util/text_fields.h"

#include <charconv>
#include <cmath>
#include <cstdio>

namespace anchormap {

std::vector<std::string_view> SplitFields(std::string_view line, bool commas_separate) {
  std::vector<std::string_view> fields;
  const auto is_separator = [commas_separate](char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || (commas_separate && c == ',');
  };
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_separator(line[i])) ++i;
    const size_t start = i;
    while (i < line.size() && !is_separator(line[i])) ++i;
    if (i > start) fields.push_back(line.substr(start, i - start));
  }
  return fields;
}

bool ParseFiniteDouble(std::string_view text, double* value) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  if (text.empty()) return false;
  double parsed = 0.0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), parsed);
  if (error != std::errc() || end != text.data() + text.size() || !std::isfinite(parsed)) {
    return false;
  }
  *value = parsed;
  return true;
}

bool ParseInt64(std::string_view text, int64_t* value) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  if (text.empty()) return false;
  int64_t parsed = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), parsed);
  if (error != std::errc() || end != text.data() + text.size()) return false;
  *value = parsed;
  return true;
}

std::string Abbreviate(std::string_view text, size_t max_chars) {
  std::string out;
  for (size_t i = 0; i < text.size() && i < max_chars; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\x%02x", c);
      out += escaped;
    }
  }
  if (text.size() > max_chars) out += "...";
  return out;
}

Status ParseNumberFields(std::string_view line, const std::vector<const char*>& names,
                         bool commas_separate, std::vector<double>* values) {
  const std::vector<std::string_view> fields = SplitFields(line, commas_separate);
  if (fields.size() != names.size()) {
    std::string layout;
    for (const char* name : names) layout += (layout.empty() ? "" : " ") + std::string(name);
    return Status::Error("expected " + std::to_string(names.size()) + " fields (" + layout +
                         "), found " + std::to_string(fields.size()));
  }
  values->assign(fields.size(), 0.0);
  for (size_t i = 0; i < fields.size(); ++i) {
    if (!ParseFiniteDouble(fields[i], &(*values)[i])) {
      return Status::Error(std::string("field ") + names[i] + " '" + Abbreviate(fields[i]) +
                           "' is not a finite number");
    }
  }
  return Status::Ok();
}

}  // namespace anchormap
