#include "common/solver/factor.h"

namespace anchormap {
namespace {

template <typename>
[[maybe_unused]] inline constexpr bool kAlwaysFalse = false;

// Raw error and (optional) Jacobians of any factor type, with the k-th key's value `value(k)`
// and its CosSin `rotation(k)`: one dispatch for the callers that hold the values in key
// order and for the packed path that gathers them by variable index. Sets `num_keys`.
template <typename Value, typename Rotation>
Eigen::Vector3d EvaluateWith(const Factor& factor, const Value& value, const Rotation& rotation,
                             Eigen::Matrix3d* J, int* num_keys) {
  return std::visit(
      [&](const auto& f) -> Eigen::Vector3d {
        using T = std::decay_t<decltype(f)>;
        if constexpr (std::is_same_v<T, PriorFactor>) {
          *num_keys = 1;
          return f.Error(value(0), J);
        } else if constexpr (std::is_same_v<T, BetweenFactor>) {
          *num_keys = 2;
          return f.Error(value(0), rotation(0), value(1), J ? &J[0] : nullptr, J ? &J[1] : nullptr);
        } else if constexpr (std::is_same_v<T, GlobalEncounterFactor>) {
          *num_keys = 2;
          return f.Error(value(0), value(1), J ? &J[0] : nullptr, J ? &J[1] : nullptr);
        } else if constexpr (std::is_same_v<T, EncounterFactor>) {
          *num_keys = 4;
          return f.Error(value(0), value(1), value(2), value(3), J);
        } else {
          static_assert(kAlwaysFalse<T>, "unhandled factor type");
        }
      },
      factor);
}

// EvaluateWith over values in key order; `rotations` (optional) holds their CosSin (Between
// computes CosSin::Of itself when not given: the same bits either way).
Eigen::Vector3d Evaluate(const Factor& factor, const Pose2* v, Eigen::Matrix3d* J,
                         const CosSin* rotations, int* num_keys) {
  return EvaluateWith(
      factor, [v](int k) -> const Pose2& { return v[k]; },
      [v, rotations](int k) { return rotations ? rotations[k] : CosSin::Of(v[k].theta()); }, J,
      num_keys);
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
  const Eigen::Vector3d error = Evaluate(factor, values, J.data(), rotations, &out.num_keys);
  static_assert(sizeof(out.jacobians) == kMaxFactorKeys * 9 * sizeof(double),
                "the Jacobians are contiguous");
  Whiten(SqrtInformation(factor), J.data(), out.num_keys, error, out.whitened_error.data(),
         out.jacobians[0].data());
  return out;
}

int LinearizePacked(const Factor& factor, const Pose2* values, const CosSin* rotations,
                    const int* vars, double* out, double* terms, double* squared) {
  std::array<Eigen::Matrix3d, kMaxFactorKeys> J;
  int num_keys = 0;
  const Eigen::Vector3d error = EvaluateWith(
      factor, [values, vars](int k) -> const Pose2& { return values[vars[k]]; },
      [rotations, vars](int k) -> const CosSin& { return rotations[vars[k]]; }, J.data(),
      &num_keys);
  Whiten(SqrtInformation(factor), J.data(), num_keys, error, out, out + 3, terms, squared);
  return num_keys;
}

double FactorChi2(const Factor& factor, const Pose2* values) {
  int num_keys = 0;
  return (SqrtInformation(factor) * Evaluate(factor, values, nullptr, nullptr, &num_keys))
      .squaredNorm();
}

}  // namespace anchormap
