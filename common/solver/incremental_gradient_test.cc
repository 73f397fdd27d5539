#include "common/solver/incremental_gradient.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace anchormap {
namespace {

using smoother_internal::FactorRecord;

// A growing graph as the smoother presents it to a pass: values by variable, the
// variables in R in elimination order, the factors, which of them count, and each
// variable's factor ids.
struct Graph {
  std::vector<Pose2> values;
  std::vector<int> position_to_var;
  std::vector<FactorRecord> factors;
  std::vector<char> counted;
  std::vector<std::vector<int64_t>> var_factors;

  void AddFactor(const Factor& factor, std::vector<int> vars) {
    FactorRecord record{factor, {}, 0, true};
    for (int v : vars) record.vars[record.num_vars++] = v;
    const int64_t id = static_cast<int64_t>(factors.size());
    for (int v : vars) {
      if (var_factors[v].empty() || var_factors[v].back() != id) var_factors[v].push_back(id);
    }
    factors.push_back(record);
    counted.push_back(1);
  }
  int AddVariable(const Pose2& value) {
    values.push_back(value);
    var_factors.emplace_back();
    position_to_var.push_back(static_cast<int>(values.size()) - 1);
    return static_cast<int>(values.size()) - 1;
  }
};

BetweenFactor MakeBetween(int a, int b, std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  BetweenFactor f;
  f.from = PoseKey{TrajectoryId(1), a};
  f.to = PoseKey{TrajectoryId(1), b};
  f.measured_T_from_to = Pose2(1.0 + 0.1 * u(*rng), 0.1 * u(*rng), 0.1 * u(*rng));
  f.sqrt_information = Eigen::Vector3d(10.0, 10.0, 30.0).asDiagonal();
  f.sqrt_information(0, 2) = 0.5 * u(*rng);
  return f;
}

// The sums as a full pass forms them: every counted factor at the values, terms added
// in factor id order.
// Each variable's position (-1 where it has none).
std::vector<int> PositionOfVariable(const Graph& graph) {
  std::vector<int> position(graph.values.size(), -1);
  for (size_t p = 0; p < graph.position_to_var.size(); ++p)
    position[graph.position_to_var[p]] = static_cast<int>(p);
  return position;
}

// Factor `id` linearised at the graph's values.
LinearizedFactor LinearizeAtValues(const Graph& graph, size_t id) {
  const FactorRecord& f = graph.factors[id];
  std::array<Pose2, kMaxFactorKeys> at;
  for (int j = 0; j < f.num_vars; ++j) at[j] = graph.values[f.vars[j]];
  return Linearize(f.factor, at.data());
}

double Reference(const Graph& graph, std::vector<Eigen::Vector3d>* g) {
  const std::vector<int> position = PositionOfVariable(graph);
  g->assign(graph.position_to_var.size(), Eigen::Vector3d::Zero());
  double chi2 = 0.0;
  for (size_t id = 0; id < graph.factors.size(); ++id) {
    if (!graph.counted[id]) continue;
    const FactorRecord& f = graph.factors[id];
    const LinearizedFactor lin = LinearizeAtValues(graph, id);
    chi2 += lin.whitened_error.squaredNorm();
    for (int j = 0; j < f.num_vars; ++j)
      (*g)[position[f.vars[j]]] += lin.jacobians[j].transpose() * lin.whitened_error;
  }
  return chi2;
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(a)) == 0; }
bool SameBits(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::memcmp(a.data(), b.data(), sizeof(double) * 3) == 0;
}

// 200 passes over a graph that grows as the smoother's does (odometry, loop closures, a
// prior), with a few variables moving between passes (some by one unit in the last
// place), sometimes nearly all, factors leaving and re-entering the sums, and now and then
// a reordering. Each pass equals a fresh object's (a full pass) bit for bit, and the
// straightforward sums to 1e-12; the work is a fraction of full passes'.
TEST(IncrementalGradientTest, EqualsAFullPassBitForBitAfterRandomUpdates) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Graph graph;
  graph.AddVariable(Pose2(0, 0, 0));
  PriorFactor prior;
  prior.key = PoseKey{TrajectoryId(1), 0};
  prior.prior = Pose2(0.01, -0.02, 0.03);
  graph.AddFactor(prior, {0});

  IncrementalGradient incremental;
  int64_t full_work = 0;
  for (int pass = 0; pass < 200; ++pass) {
    const int n = static_cast<int>(graph.values.size());
    const int kind = static_cast<int>(rng() % 10);
    if (kind < 4) {  // an update: a new pose by odometry, sometimes a loop closure
      const int v = graph.AddVariable(Pose2(n + 0.1 * u(rng), u(rng), u(rng)));
      graph.AddFactor(MakeBetween(v - 1, v, &rng), {v - 1, v});
      if (rng() % 2 && n > 3) {
        const int old = static_cast<int>(rng() % (n - 2));
        graph.AddFactor(MakeBetween(old, v, &rng), {old, v});
      }
    } else if (kind < 7) {  // a few move
      for (int m = static_cast<int>(rng() % 4); m > 0; --m) {
        Pose2& value = graph.values[rng() % n];
        const double x = rng() % 2 ? std::nextafter(value.x(), 1e9) : value.x() + 0.01;
        value = Pose2(x, value.y(), value.theta() + 0.001 * u(rng));
      }
    } else if (kind < 8) {  // a correction step: nearly all move
      for (Pose2& value : graph.values) {
        if (rng() % 10) value = Pose2(value.x() + 1e-3 * u(rng), value.y(), value.theta());
      }
    } else if (kind < 9) {  // factors leave or re-enter the sums
      for (int m = 0; m < 3; ++m) {
        char& c = graph.counted[rng() % graph.counted.size()];
        c = c ? 0 : 1;
      }
    } else {  // a reordering
      std::shuffle(graph.position_to_var.begin(), graph.position_to_var.end(), rng);
    }

    const double chi2 = incremental.Pass(graph.values, graph.position_to_var, graph.factors,
                                         graph.counted, graph.var_factors);
    IncrementalGradient fresh;
    const double fresh_chi2 = fresh.Pass(graph.values, graph.position_to_var, graph.factors,
                                         graph.counted, graph.var_factors);
    full_work += fresh.linearized();
    std::vector<Eigen::Vector3d> g;
    const double reference_chi2 = Reference(graph, &g);

    SCOPED_TRACE("pass " + std::to_string(pass));
    EXPECT_TRUE(SameBits(chi2, fresh_chi2)) << chi2 << " vs " << fresh_chi2;
    EXPECT_NEAR(chi2, reference_chi2, 1e-12 * reference_chi2);
    ASSERT_EQ(incremental.g().size(), g.size());
    for (size_t p = 0; p < g.size(); ++p) {
      EXPECT_TRUE(SameBits(incremental.g()[p], fresh.g()[p])) << "position " << p;
      EXPECT_LT((incremental.g()[p] - g[p]).norm(), 1e-12 * (1.0 + g[p].norm()));
    }
  }
  EXPECT_EQ(incremental.passes(), 200);
  EXPECT_LT(incremental.linearized(), full_work / 3);
}

// The conjugate gradients' product J^T J p: the counted factors, linearised at the pass's
// values, at their positions (here reversed, and again after a reordering), against the
// dense J^T J p of the same factors.
TEST(IncrementalGradientTest, MultiplyNormalIsTheCountedFactorsDenseProduct) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Graph graph;
  for (int v = 0; v < 6; ++v) graph.AddVariable(Pose2(v, 0.1 * v, 0.1 * u(rng)));
  for (int v = 1; v < 6; ++v) graph.AddFactor(MakeBetween(v - 1, v, &rng), {v - 1, v});
  graph.AddFactor(MakeBetween(0, 4, &rng), {0, 4});
  graph.counted[2] = 0;
  std::reverse(graph.position_to_var.begin(), graph.position_to_var.end());
  IncrementalGradient gradient;
  for (int round = 0; round < 2; ++round) {
    if (round == 1) std::shuffle(graph.position_to_var.begin(), graph.position_to_var.end(), rng);
    gradient.Pass(graph.values, graph.position_to_var, graph.factors, graph.counted,
                  graph.var_factors);
    const int n = static_cast<int>(graph.position_to_var.size());
    const std::vector<int> position = PositionOfVariable(graph);
    // Dense J (rows: counted factors' 3 residuals; columns: 3 per position).
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(3 * 6, 3 * n);
    int rows = 0;
    for (size_t id = 0; id < graph.factors.size(); ++id) {
      if (!graph.counted[id]) continue;
      const FactorRecord& f = graph.factors[id];
      const LinearizedFactor lin = LinearizeAtValues(graph, id);
      for (int j = 0; j < f.num_vars; ++j)
        J.block<3, 3>(rows, 3 * position[f.vars[j]]) = lin.jacobians[j];
      rows += 3;
    }
    ASSERT_EQ(rows, 3 * 5);
    std::vector<Eigen::Vector3d> p(n), q(n, Eigen::Vector3d::Constant(7.0));
    Eigen::VectorXd dense_p(3 * n);
    for (int k = 0; k < n; ++k) {
      p[k] = Eigen::Vector3d(u(rng), u(rng), u(rng));
      dense_p.segment<3>(3 * k) = p[k];
    }
    const Eigen::VectorXd jp = J * dense_p;
    const Eigen::VectorXd dense_q = J.transpose() * jp;
    const double pq = gradient.MultiplyNormal(p, &q);
    EXPECT_NEAR(pq, jp.squaredNorm(), 1e-9 * jp.squaredNorm());
    for (int k = 0; k < n; ++k) {
      EXPECT_LT((q[k] - dense_q.segment<3>(3 * k)).norm(), 1e-9 * (1.0 + dense_q.norm()))
          << "position " << k;
    }
  }
}

}  // namespace
}  // namespace anchormap
