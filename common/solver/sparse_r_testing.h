#pragma once
// Test helpers for R's block-row forms (SparseR, FlatR, PathSolve): R as a dense matrix for
// the oracle, and random measurement rows to eliminate into it.

#include <random>

#include <Eigen/Core>

#include "common/solver/sparse_r.h"

namespace anchormap {

// R with its blocks as stored (a dense oracle for the triangular solves).
inline Eigen::MatrixXd DenseR(const SparseR& r) {
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(3 * r.size(), 3 * r.size());
  for (int p = 0; p < r.size(); ++p) {
    R.block<3, 3>(3 * p, 3 * p) = r.row(p).diagonal;
    for (const auto& [q, block] : r.row(p).right) R.block<3, 3>(3 * p, 3 * q) = block;
  }
  return R;
}

// One random measurement between two variables (a loop closure when they are far apart;
// b < 0: a prior on a), well conditioned on a.
inline NewRows RandomBetweenRows(int a, int b, std::mt19937* rng) {
  std::normal_distribution<double> g;
  NewRows rows;
  Eigen::Matrix3d ja, jb;
  for (int i = 0; i < 9; ++i) ja(i) = g(*rng);
  for (int i = 0; i < 9; ++i) jb(i) = g(*rng);
  rows.blocks.emplace_back(a, ja + 3 * Eigen::Matrix3d::Identity());
  if (b >= 0) rows.blocks.emplace_back(b, jb);
  rows.rhs = Eigen::Vector3d(g(*rng), g(*rng), g(*rng));
  return rows;
}

}  // namespace anchormap
