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

namespace {

// S * J_k entry by entry, the products summed in Eigen's order (`jacobians`: 9 doubles per
// key, column-major), and S * e: Eigen's packet product read J_k in 16-byte loads right
// after Evaluate's 8-byte stores of it, a store forwarding stall that perf put at two
// thirds of Linearize. With `terms`, also J_k^T e per key and |e|^2 as
// PackedGradientTerms sums them, from the values in registers (read back from where they
// were just stored, in the wider loads the compiler picks, they would wait the same way).
void Whiten(const Eigen::Matrix3d& S, const Eigen::Matrix3d* J, int num_keys,
            const Eigen::Vector3d& error, double* whitened_error, double* jacobians,
            double* terms = nullptr, double* squared = nullptr) {
  const Eigen::Vector3d e = S * error;
  for (int k = 0; k < num_keys; ++k) {
    const double* j = J[k].data();
    double o[9];  // in registers; stored entry by entry
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) {
        o[r + 3 * c] = S(r, 0) * j[3 * c] + S(r, 1) * j[1 + 3 * c] + S(r, 2) * j[2 + 3 * c];
        jacobians[9 * k + r + 3 * c] = o[r + 3 * c];
      }
    }
    if (terms != nullptr) {
      for (int c = 0; c < 3; ++c)
        terms[3 * k + c] = (o[3 * c] * e[0] + o[3 * c + 1] * e[1]) + o[3 * c + 2] * e[2];
    }
  }
  whitened_error[0] = e[0];
  whitened_error[1] = e[1];
  whitened_error[2] = e[2];
  if (squared != nullptr) *squared = (e[0] * e[0] + e[1] * e[1]) + e[2] * e[2];
}

}  // namespace

void PackedGradientTerms(const double* entry, int num_keys, double* terms, double* squared) {
  const double* whitened_error = entry;
  const double* jacobians = entry + 3;
  const double e0 = whitened_error[0], e1 = whitened_error[1], e2 = whitened_error[2];
  for (int k = 0; k < num_keys; ++k) {
    const double* j = jacobians + 9 * k;
    for (int c = 0; c < 3; ++c)
      terms[3 * k + c] = (j[3 * c] * e0 + j[3 * c + 1] * e1) + j[3 * c + 2] * e2;
  }
  *squared = (e0 * e0 + e1 * e1) + e2 * e2;
}

LinearizedFactor Linearize(const Factor& factor, const Pose2* values, const CosSin* rotations) {
  LinearizedFactor out;
  std::array<Eigen::Matrix3d, kMaxFactorKeys> J;
  const Eigen::Vector3d error = Evaluate(factor, values, J.data(), rotations);
  out.num_keys = NumKeys(factor);
  static_assert(sizeof(out.jacobians) == kMaxFactorKeys * 9 * sizeof(double),
                "the Jacobians are contiguous");
  Whiten(SqrtInformation(factor), J.data(), out.num_keys, error, out.whitened_error.data(),
         out.jacobians[0].data());
  return out;
}

int LinearizePacked(const Factor& factor, const Pose2* values, const CosSin* rotations,
                    const int* vars, double* out, double* terms, double* squared) {
  std::array<Eigen::Matrix3d, kMaxFactorKeys> J;
  const int num_keys = std::visit(
      [&](const auto& f) -> int {
        using T = std::decay_t<decltype(f)>;
        Eigen::Vector3d error;
        int keys = 0;
        if constexpr (std::is_same_v<T, PriorFactor>) {
          error = f.Error(values[vars[0]], &J[0]);
          keys = 1;
        } else if constexpr (std::is_same_v<T, BetweenFactor>) {
          error = f.Error(values[vars[0]], rotations[vars[0]], values[vars[1]], &J[0], &J[1]);
          keys = 2;
        } else if constexpr (std::is_same_v<T, GlobalEncounterFactor>) {
          error = f.Error(values[vars[0]], values[vars[1]], &J[0], &J[1]);
          keys = 2;
        } else if constexpr (std::is_same_v<T, EncounterFactor>) {
          error =
              f.Error(values[vars[0]], values[vars[1]], values[vars[2]], values[vars[3]], J.data());
          keys = 4;
        } else {
          static_assert(kAlwaysFalse<T>, "unhandled factor type");
        }
        Whiten(f.sqrt_information, J.data(), keys, error, out, out + 3, terms, squared);
        return keys;
      },
      factor);
  return num_keys;
}

double FactorChi2(const Factor& factor, const Pose2* values) {
  return (SqrtInformation(factor) * Evaluate(factor, values, nullptr)).squaredNorm();
}

}  // namespace anchormap
