// Quadric error metrics (Garland and Heckbert, "Surface simplification
// using quadric error metrics", 1997) and the robust minimizer of Lindstrom
// ("Out-of-core simplification of large polygonal models", 2000): the
// minimization restricted to the well-conditioned eigen-directions of the
// quadric, relative to the cluster's mean.
#include "quadric.h"

#include <cmath>
#include <utility>

namespace psq::detail {

double Quadric::error(const double x[3]) const {
  const double ax0 = a[0] * x[0] + a[1] * x[1] + a[2] * x[2];
  const double ax1 = a[1] * x[0] + a[3] * x[1] + a[4] * x[2];
  const double ax2 = a[2] * x[0] + a[4] * x[1] + a[5] * x[2];
  return x[0] * ax0 + x[1] * ax1 + x[2] * ax2 + 2 * (b[0] * x[0] + b[1] * x[1] + b[2] * x[2]) + c;
}

void symmetric_eigen(const double a[6], double w[3], double v[3][3]) {
  double m[3][3] = {{a[0], a[1], a[2]}, {a[1], a[3], a[4]}, {a[2], a[4], a[5]}};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) v[i][j] = i == j ? 1.0 : 0.0;
  // Cyclic Jacobi: each rotation zeroes one off-diagonal element; a 3x3
  // matrix converges to double precision in a handful of sweeps.
  for (int sweep = 0; sweep < 32; ++sweep) {
    const double off = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
    const double diag = m[0][0] * m[0][0] + m[1][1] * m[1][1] + m[2][2] * m[2][2];
    // Off-diagonal elements 1e-12 of the diagonal's: far below the 1e-3
    // by which minimize_quadric() tells directions apart, and eigenvectors
    // accurate enough that no part of a large direction's step leaks into
    // a small one's (divided by its small eigenvalue).
    if (off <= 1e-24 * diag || off == 0) break;
    for (int p = 0; p < 2; ++p) {
      for (int q = p + 1; q < 3; ++q) {
        if (m[p][q] == 0) continue;
        const double theta = (m[q][q] - m[p][p]) / (2 * m[p][q]);
        const double t = (theta >= 0 ? 1.0 : -1.0) / (std::fabs(theta) + std::sqrt(theta * theta + 1));
        const double c = 1 / std::sqrt(t * t + 1), s = t * c;
        for (int k = 0; k < 3; ++k) {  // m = m J (columns p and q)
          const double mkp = m[k][p], mkq = m[k][q];
          m[k][p] = c * mkp - s * mkq;
          m[k][q] = s * mkp + c * mkq;
        }
        for (int k = 0; k < 3; ++k) {  // m = J^T m (rows p and q)
          const double mpk = m[p][k], mqk = m[q][k];
          m[p][k] = c * mpk - s * mqk;
          m[q][k] = s * mpk + c * mqk;
        }
        for (int k = 0; k < 3; ++k) {  // v = v J
          const double vkp = v[k][p], vkq = v[k][q];
          v[k][p] = c * vkp - s * vkq;
          v[k][q] = s * vkp + c * vkq;
        }
      }
    }
  }
  for (int i = 0; i < 3; ++i) w[i] = m[i][i];
}

void minimize_quadric(const Quadric& q, const double mean[3], double tolerance, double x[3]) {
  for (int i = 0; i < 3; ++i) x[i] = mean[i];
  double w[3], v[3][3];
  symmetric_eigen(q.a, w, v);
  const double largest = std::fmax(std::fabs(w[0]), std::fmax(std::fabs(w[1]), std::fabs(w[2])));
  if (!(largest > 0) || !std::isfinite(largest)) return;
  // The residual r = -(A mean + b); the step from the mean is
  // sum over kept directions of (v_i . r / w_i) v_i.
  const double r[3] = {-(q.a[0] * mean[0] + q.a[1] * mean[1] + q.a[2] * mean[2] + q.b[0]),
                       -(q.a[1] * mean[0] + q.a[3] * mean[1] + q.a[4] * mean[2] + q.b[1]),
                       -(q.a[2] * mean[0] + q.a[4] * mean[1] + q.a[5] * mean[2] + q.b[2])};
  for (int i = 0; i < 3; ++i) {
    if (!(w[i] > tolerance * largest)) continue;  // a quadric is positive semidefinite: small or negative is noise
    const double proj = (v[0][i] * r[0] + v[1][i] * r[1] + v[2][i] * r[2]) / w[i];
    for (int k = 0; k < 3; ++k) x[k] += proj * v[k][i];
  }
}

}  // namespace psq::detail
