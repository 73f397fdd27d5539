#include "server/match_budget.h"

#include <cmath>

#include "server/data_time_tokens.h"

namespace anchormap {

Status MatchBudgetOptions::Validate(const std::string& prefix) const {
  if (!(units_per_s >= 0) || !std::isfinite(units_per_s)) {
    return Status::Error(prefix + "_per_s must be finite and >= 0");
  }
  if (!(burst >= 0) || !std::isfinite(burst)) {
    return Status::Error(prefix + "_burst must be finite and >= 0");
  }
  if (!(skip_priority_m >= 0) || !std::isfinite(skip_priority_m)) {
    return Status::Error(prefix + "_skip_priority_m must be finite and >= 0");
  }
  return Status::Ok();
}

void MatchBudget::Advance(int64_t now_utime) {
  RefillTokens(now_utime, options_.units_per_s, options_.burst, &tokens_, &last_utime_);
}

void MatchBudget::Spend(double units) {
  if (!bounded()) return;
  tokens_ -= units;
  spent_ += units;
}

double MatchBudget::Priority(const BudgetRequest& request) const {
  const auto ledger = ledgers_.find(request.key.trajectory);
  if (ledger == ledgers_.end()) return request.driven_m;
  return request.driven_m - ledger->second.driven_m +
         options_.skip_priority_m * static_cast<double>(ledger->second.skips);
}

void MatchBudget::Served(const BudgetRequest& request, double units) {
  ledgers_[request.key.trajectory] = Ledger{request.driven_m, 0};
  Spend(units);
}

std::vector<PoseKey> MatchBudget::Serve(const std::vector<BudgetRequest>& requests,
                                        double max_units,
                                        const std::function<double(PoseKey)>& serve) {
  if (!bounded() || tokens_ >= max_units * static_cast<double>(requests.size())) {
    // Enough for all: arrival order, as without a budget.
    for (const BudgetRequest& request : requests) {
      const double units = serve(request.key);
      if (bounded()) Served(request, units);
    }
    return {};
  }
  std::vector<bool> done(requests.size(), false);
  std::vector<PoseKey> skipped;
  for (size_t round = 0; round < requests.size() && tokens_ > 0; ++round) {
    // The highest priority left (the first in arrival order on ties); priorities change as
    // keyframes of the same trajectory are served.
    size_t best = requests.size();
    double best_priority = 0.0;
    for (size_t i = 0; i < requests.size(); ++i) {
      if (done[i]) continue;
      const double priority = Priority(requests[i]);
      if (best == requests.size() || priority > best_priority) {
        best = i;
        best_priority = priority;
      }
    }
    done[best] = true;
    Served(requests[best], serve(requests[best].key));
  }
  for (size_t i = 0; i < requests.size(); ++i) {
    if (done[i]) continue;
    ++ledgers_[requests[i].key.trajectory].skips;
    skipped.push_back(requests[i].key);
  }
  skipped_ += static_cast<int64_t>(skipped.size());
  return skipped;
}

void MatchBudget::ImportState(State s) {
  tokens_ = s.tokens;
  last_utime_ = s.last_utime;
  ledgers_ = std::move(s.ledgers);
  spent_ = s.spent;
  skipped_ = s.skipped;
}

}  // namespace anchormap
