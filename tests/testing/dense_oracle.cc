#include "tests/testing/dense_oracle.h"

#include <stdexcept>

namespace anchormap::testing {

DenseOracle::DenseOracle(std::vector<Factor> factors) : factors_(std::move(factors)) {}

void DenseOracle::Linearize(const Values& values, Eigen::MatrixXd* A, Eigen::VectorXd* b) const {
  std::map<Key, int, KeyLess> column;
  for (const auto& [key, value] : values) column.emplace(key, 3 * static_cast<int>(column.size()));
  A->setZero(3 * factors_.size(), 3 * values.size());
  b->setZero(3 * factors_.size());
  for (size_t f = 0; f < factors_.size(); ++f) {
    const std::vector<Key> keys = FactorKeys(factors_[f]);
    std::vector<Pose2> at;
    for (const Key& key : keys) at.push_back(values.at(key));
    const LinearizedFactor lin = anchormap::Linearize(factors_[f], at.data());
    for (size_t k = 0; k < keys.size(); ++k) {
      A->block<3, 3>(3 * f, column.at(keys[k])) = lin.jacobians[k];
    }
    b->segment<3>(3 * f) = lin.whitened_error;
  }
}

Eigen::MatrixXd DenseOracle::Covariance(const Values& values, const std::vector<Key>& keys) const {
  Eigen::MatrixXd A;
  Eigen::VectorXd b;
  Linearize(values, &A, &b);
  const Eigen::MatrixXd sigma = (A.transpose() * A).inverse();
  std::map<Key, int, KeyLess> column;
  for (const auto& [key, value] : values) column.emplace(key, 3 * static_cast<int>(column.size()));
  Eigen::MatrixXd out(3 * keys.size(), 3 * keys.size());
  for (size_t i = 0; i < keys.size(); ++i) {
    for (size_t j = 0; j < keys.size(); ++j) {
      out.block<3, 3>(3 * i, 3 * j) = sigma.block<3, 3>(column.at(keys[i]), column.at(keys[j]));
    }
  }
  return out;
}

Values DenseOracle::Solve(Values values, double tolerance, int max_iterations) const {
  for (int it = 0; it < max_iterations; ++it) {
    Eigen::MatrixXd A;
    Eigen::VectorXd b;
    Linearize(values, &A, &b);
    const Eigen::VectorXd step = (A.transpose() * A).ldlt().solve(-A.transpose() * b);
    int k = 0;
    for (auto& [key, value] : values) {
      value = Pose2(value.x() + step[k], value.y() + step[k + 1], value.theta() + step[k + 2]);
      k += 3;
    }
    if (step.cwiseAbs().maxCoeff() < tolerance) break;
  }
  return values;
}

double DenseOracle::Chi2(const Values& values) const {
  double chi2 = 0.0;
  for (const Factor& factor : factors_) {
    std::vector<Pose2> at;
    for (const Key& key : FactorKeys(factor)) at.push_back(values.at(key));
    chi2 += FactorChi2(factor, at.data());
  }
  return chi2;
}

}  // namespace anchormap::testing
