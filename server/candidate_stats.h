#pragma once
// What happened to the candidates of a scan-matching source (loop closures, scan
// encounters), by reason. These are not input refusals (RejectCounter): a candidate that
// fails is a place that did not match, which is normal.

#include <cstdint>
#include <cstdio>
#include <string>

namespace anchormap {

struct CandidateStats {
  int64_t candidates = 0;     // candidates matched
  int64_t accepted = 0;       // entered the graph
  int64_t no_match = 0;       // no pose above the matcher's min score
  int64_t weak_match = 0;     // a pose, but score or overlap below the bars
  int64_t gate_rejected = 0;  // disagreed with the estimate beyond the chi-square gate
  int64_t kept = 0;           // waiting for a consistent second (server/held_matches.h)
  int64_t unconfirmed = 0;    // given up without one (too old, too many, end of input)
  int64_t repeated = 0;       // the pair this source had already joined: not entered twice

  int64_t rejected() const { return no_match + weak_match + gate_rejected + unconfirmed; }
  std::string Summary(const std::string& name) const {
    char text[256];
    std::snprintf(text, sizeof(text),
                  "%s: candidates %lld accepted %lld no_match %lld weak %lld gate %lld kept %lld "
                  "unconfirmed %lld repeated %lld",
                  name.c_str(), static_cast<long long>(candidates),
                  static_cast<long long>(accepted), static_cast<long long>(no_match),
                  static_cast<long long>(weak_match), static_cast<long long>(gate_rejected),
                  static_cast<long long>(kept), static_cast<long long>(unconfirmed),
                  static_cast<long long>(repeated));
    return text;
  }
};

}  // namespace anchormap
