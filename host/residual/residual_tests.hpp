#pragma once
// Stages 2 and 3 of the residual loop: tests of the base model's residual (whiteness per channel
// and mode, correlation with candidate explanatory signals) and the trace of the unexplained heat
// per node (inverse method on the residual).
#include "host/residual/residual_loop.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace btsm::residual {

struct ResidualTestsResult {
  std::vector<ChannelDiagnostics> diagnostics;
  bool all_white = true;
};

// `nodes_*` are the base model's node temperatures per recording, `resid_*` its residuals.
ResidualTestsResult test_residuals(const thermal::Network& net, const std::vector<thermal::Recording>& fit,
                                   const std::vector<thermal::Recording>& check, const std::vector<Eigen::MatrixXd>& nodes_fit,
                                   const std::vector<Eigen::MatrixXd>& nodes_check, const std::vector<Eigen::MatrixXd>& resid_fit,
                                   const std::vector<Eigen::MatrixXd>& resid_check, double whiteness_p, double correlation_p);

// The heat the base model does not explain at each measured node of one recording, over time:
// Tikhonov (first order) with GCV's alpha on the base model (keep_model_sources), steps of
// `step_s` (0 = max(60 s, 10 samples)), noise level `noise_sigma_k`. Throws what the inverse
// method throws.
std::vector<NodeTrace> trace_unexplained_heat(const thermal::Network& net, const Eigen::VectorXd& params,
                                              const thermal::Recording& rec, const Eigen::VectorXd& x0, double step_s,
                                              double noise_sigma_k);

}  // namespace btsm::residual
