#include "common/solver/factor.h"

namespace anchormap {
namespace {

template <typename>
[[maybe_unused]] inline constexpr bool kAlwaysFalse = false;

// Raw error and (optional) Jacobians for any factor type; `rotations` (optional) holds
// the values' CosSin.
Eigen::Vector3d Evaluate(const Factor& factor, const Pose2* v, Eigen::Matrix3d* J,
                         const CosSin* rotations = nullptr) {
  return std::visit(
      [&](const auto& f) -> Eigen::Vector3d {
        using T = std::decay_t<decltype(f)>;
        if constexpr (std::is_same_v<T, PriorFactor>) {
          return f.Error(v[0], J);
        } else if constexpr (std::is_same_v<T, BetweenFactor>) {
          // Between computes CosSin::Of itself when not given: the same bits either way.
          return f.Error(v[0], rotations ? rotations[0] : CosSin::Of(v[0].theta()), v[1],
                         J ? &J[0] : nullptr, J ? &J[1] : nullptr);
        } else if constexpr (std::is_same_v<T, GlobalEncounterFactor>) {
          return f.Error(v[0], v[1], J ? &J[0] : nullptr, J ? &J[1] : nullptr);
        } else if constexpr (std::is_same_v<T, EncounterFactor>) {
          return f.Error(v[0], v[1], v[2], v[3], J);
        } else {
          static_assert(kAlwaysFalse<T>, "unhandled factor type");
        }
      },
      factor);
}

// The number of keys of a factor, without building the key list (Linearize runs for every
// factor in every correction step).
int NumKeys(const Factor& factor) {
  return std::visit(
      [](const auto& f) -> int {
        using T = std::decay_t<decltype(f)>;
        if constexpr (std::is_same_v<T, PriorFactor>) {
          return 1;
        } else if constexpr (std::is_same_v<T, BetweenFactor> ||
                             std::is_same_v<T, GlobalEncounterFactor>) {
          return 2;
        } else if constexpr (std::is_same_v<T, EncounterFactor>) {
          return 4;
        } else {
          static_assert(kAlwaysFalse<T>, "unhandled factor type");
        }
      },
      factor);
}

const Eigen::Matrix3d& SqrtInformation(const Factor& factor) {
  return std::visit([](const auto& f) -> const Eigen::Matrix3d& { return f.sqrt_information; },
                    factor);
}

}  // namespace

std::vector<Key> FactorKeys(const Factor& factor) {
  return std::visit([](const auto& f) { return f.keys(); }, factor);
}

LinearizedFactor Linearize(const Factor& factor, const Pose2* values) {
  return Linearize(factor, values, nullptr);
}

LinearizedFactor Linearize(const Factor& factor, const Pose2* values, const CosSin* rotations) {
  LinearizedFactor out;
  std::array<Eigen::Matrix3d, kMaxFactorKeys> J;
  const Eigen::Vector3d error = Evaluate(factor, values, J.data(), rotations);
  const Eigen::Matrix3d& S = SqrtInformation(factor);
  out.num_keys = NumKeys(factor);
  // S * J_k entry by entry, the products summed in Eigen's order: its packet product
  // read J_k in 16-byte loads right after Evaluate's 8-byte stores of it, a store
  // forwarding stall that perf put at two thirds of this function.
  for (int k = 0; k < out.num_keys; ++k) {
    const double* j = J[k].data();
    double* o = out.jacobians[k].data();
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r)
        o[r + 3 * c] = S(r, 0) * j[3 * c] + S(r, 1) * j[1 + 3 * c] + S(r, 2) * j[2 + 3 * c];
    }
  }
  out.whitened_error = S * error;
  return out;
}

double FactorChi2(const Factor& factor, const Pose2* values) {
  return (SqrtInformation(factor) * Evaluate(factor, values, nullptr)).squaredNorm();
}

}  // namespace anchormap
