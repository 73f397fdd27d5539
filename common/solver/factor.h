#pragma once
// The factors of the multi-robot pose graph, as one closed set of value types
// (std::variant): the smoother owns them by value, journals can copy them, and every
// switch over them is checked for exhaustiveness by the compiler.
//
// Each factor type provides:
//   keys()                       the variables it constrains, in Jacobian order
//   Error(values, jacobians)     e(x) = h(x) - z (angle wrapped), with dh/dx per key
//   sqrt_information             S with S^T S = information; whitened residual is S e

#include <array>
#include <variant>
#include <vector>

#include <Eigen/Core>

#include "common/solver/between_factor.h"
#include "common/solver/encounter_factor.h"
#include "common/solver/global_encounter_factor.h"
#include "common/solver/prior_factor.h"

namespace anchormap {

using Factor = std::variant<PriorFactor, BetweenFactor, EncounterFactor, GlobalEncounterFactor>;

// At most four variables per factor (the relative encounter).
constexpr int kMaxFactorKeys = 4;

// A factor linearised at some values: whitened Jacobian blocks and whitened residual.
struct LinearizedFactor {
  int num_keys = 0;
  std::array<Eigen::Matrix3d, kMaxFactorKeys> jacobians;  // S * dh/dx_k
  Eigen::Vector3d whitened_error;                         // S * e(x)
};

std::vector<Key> FactorKeys(const Factor& factor);

// Linearises `factor` at `values` (one Pose2 per key, in FactorKeys order).
LinearizedFactor Linearize(const Factor& factor, const Pose2* values);
// The same with `rotations[k]` = CosSin::Of(values[k].theta()) given, for a caller that
// linearises many factors at the same values (the same bits).
LinearizedFactor Linearize(const Factor& factor, const Pose2* values, const CosSin* rotations);
// The same written packed at `out` (LinearizationCache's entries): S e, then each S J_k
// column-major, 3 + 9 x keys doubles; the values are those of `values` and `rotations`
// (by variable) at `vars` (the factor's, in key order), read in place. With `terms`, also
// the factor's gradient terms J_k^T e (3 doubles per key) and |e|^2 in `squared`, summed as
// Eigen's `jacobian.transpose() * whitened_error` and `squaredNorm()` sum them. Returns the
// keys. The same bits as Linearize: the gradient passes linearise every factor after a
// step, and a gathered copy of the values, a returned LinearizedFactor (320 bytes) and
// wide loads of what was just stored narrow were a third of that cost.
int LinearizePacked(const Factor& factor, const Pose2* values, const CosSin* rotations,
                    const int* vars, double* out, double* terms = nullptr,
                    double* squared = nullptr);

// The gradient terms of a packed entry (as LinearizePacked gives them): J_k^T e per key
// and |e|^2, the first two products summed first, then the third. The entry is read in
// 8-byte units, as LinearizePacked writes it: a wider load of what was just stored narrow
// waits for the stores to retire.
void PackedGradientTerms(const double* entry, int num_keys, double* terms, double* squared);

// Squared whitened residual |S e(x)|^2 at `values`.
double FactorChi2(const Factor& factor, const Pose2* values);

}  // namespace anchormap
