// htfeti spectrum against the paper's Table 1 (h = 1/64, P1 elements, edge averages), with the
// misprints corrected as DESIGN.md lists them. Each value must round to the printed digits,
// except lambda_max for m = 4, which is 2.80972 against a printed 2.8098 (one unit in the last
// digit; docs/results.md).
#include <gtest/gtest.h>

#include <cmath>

#include "htfeti/spectrum.hpp"

using namespace htfeti;

TEST(Table1, ClusterOf2x2) {
  const auto s = cluster_spectrum(2, 64, ElementKind::p1);
  EXPECT_EQ(s.H_over_h, 32);
  EXPECT_NEAR(s.lambda_max, 2.8235, 0.5e-4);
  EXPECT_NEAR(s.lambda_min, 0.0173, 0.5e-4);
  EXPECT_NEAR(s.lambda_min_estimate, 0.0104, 0.5e-4);
}

TEST(Table1, ClusterOf4x4) {
  const auto s = cluster_spectrum(4, 64, ElementKind::p1);
  EXPECT_EQ(s.H_over_h, 16);
  EXPECT_NEAR(s.lambda_max, 2.8098, 1.0e-4);
  EXPECT_NEAR(s.lambda_min, 0.0093, 0.5e-4);           // printed 0.093 (misprint)
  EXPECT_NEAR(s.lambda_min_estimate, 0.0059, 0.5e-4);  // printed 0.059 (misprint)
}

TEST(Table1, BoundsOfTheTheoremHold) {
  for (int m : {2, 4}) {
    const auto s = cluster_spectrum(m, 32, ElementKind::q1);
    EXPECT_LE(s.lambda_max, s.subdomain_lambda_max * (1 + 1e-12));  // (18)
    EXPECT_LE(s.lambda_min, s.subdomain_lambda_min);                // (19), left
    EXPECT_GE(s.lambda_min, s.lambda_min_estimate);                 // (19), right
  }
  // With Q1 the largest eigenvalue of a subdomain Schur complement is sqrt(3) (issue note).
  EXPECT_NEAR(cluster_spectrum(2, 32, ElementKind::q1).subdomain_lambda_max, std::sqrt(3.0), 1e-3);
}

TEST(Table1, BadArguments) {
  EXPECT_THROW(cluster_spectrum(3, 64, ElementKind::p1), std::invalid_argument);
  EXPECT_THROW(cluster_spectrum(64, 64, ElementKind::p1), std::invalid_argument);
}
