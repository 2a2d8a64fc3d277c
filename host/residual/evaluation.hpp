#pragma once
// Evaluating a (base or augmented) network on recordings: model temperatures at the measured
// columns with the least-squares initial state, residuals, error metrics and information criteria.
#include "host/thermal/network.hpp"
#include "host/thermal/recording.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <vector>

namespace btsm::residual {

struct ErrorMetrics {
  double rmse_k = 0;     // over all measured cells
  double nmse_min = 0;   // worst channel, NMSE = 1 - |e|^2 / |y - mean y|^2 (paper Eq. A7)
  double max_abs_k = 0;
  std::size_t cells = 0;
};

// Model temperatures at the measured columns and residuals (measured - model) for one recording,
// with the initial state estimated by linear least squares (the response is affine in x0) unless
// given. A drifting measurement's drift is part of the model temperature at its column, with its
// least-squares offset for the recording (thermal/network.hpp).
struct Evaluation {
  Eigen::MatrixXd model_c;     // rows x columns
  Eigen::MatrixXd residual_k;  // rows x columns, NaN where not measured
  Eigen::MatrixXd nodes_c;     // rows x nodes
  Eigen::VectorXd x0_c;
};
// `rest_nodes` start at the first row's ambient (virtual states at rest when a recording starts).
Evaluation evaluate_model(const thermal::Network& net, const Eigen::VectorXd& params, const thermal::Recording& rec,
                          const Eigen::MatrixXd* extra_heat_w = nullptr, const Eigen::VectorXd* x0_c = nullptr,
                          const std::vector<int>& rest_nodes = {});

ErrorMetrics error_metrics(const std::vector<Eigen::MatrixXd>& residual_k, const std::vector<Eigen::MatrixXd>& measured_c);

// Measured values at the network's columns, per recording (rows x columns, NaN = missing).
std::vector<Eigen::MatrixXd> measured_columns_of(const thermal::Network& net, const std::vector<thermal::Recording>& recs);

// Sum of squares and count of the finite cells.
double sum_of_squares(const std::vector<Eigen::MatrixXd>& residual_k, std::size_t& cells);

// n log(RSS/n) + k log(n): the Bayesian information criterion of a Gaussian fit with k unknowns.
double bic(double rss, std::size_t n, int k);

}  // namespace btsm::residual
