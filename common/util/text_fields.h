#pragma once
// Splitting text lines into fields and strict number parsing for the line-based file formats
// (CARMEN logs, TUM trajectories, relations files, g2o). Strict means a whole field must be
// one finite number: "1.5x", "", "nan" and "inf" are rejected, so a corrupt line is reported
// instead of silently read as zeros (what atof and CARMEN's own strtod-based reader do).

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/util/status.h"

namespace anchormap {

// Splits `line` at runs of spaces, tabs, '\r' and '\n' (and ',' when `commas_separate` is
// true). Empty fields are never returned. The views point into `line`.
std::vector<std::string_view> SplitFields(std::string_view line, bool commas_separate = false);

// Parses the whole of `text` as a finite double (an optional leading '+' is accepted).
bool ParseFiniteDouble(std::string_view text, double* value);

// Parses the whole of `text` as a decimal integer.
bool ParseInt64(std::string_view text, int64_t* value);

// Parses a line of exactly `names.size()` finite numbers (split as SplitFields does) into
// `values`, in order. The error names the field, e.g. "field qw 'x' is not a finite number",
// or the expected layout "expected 8 fields (t1 t2 x y z roll pitch yaw), found 7".
Status ParseNumberFields(std::string_view line, const std::vector<const char*>& names,
                         bool commas_separate, std::vector<double>* values);

// `text` for an error message: at most `max_chars` characters ("..." appended when cut),
// bytes outside printable ASCII written as \xNN.
std::string Abbreviate(std::string_view text, size_t max_chars = 32);

}  // namespace anchormap
