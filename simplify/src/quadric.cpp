// SPDX-License-Identifier: Apache-2.0
// Quadric error metrics (Garland and Heckbert, "Surface simplification
// using quadric error metrics", 1997) and the robust minimizer of Lindstrom
// ("Out-of-core simplification of large polygonal models", 2000): the
// minimization restricted to the well-conditioned eigen-directions of the
// quadric, relative to the cluster's mean. The eigenvalues come in closed
// form (Smith, "Eigenvalues of a symmetric 3 x 3 matrix", 1961), and the
// one eigenvector a case needs from a cross product of two rows of
// A - lambda I (well defined when lambda is apart from the others); cyclic
// Jacobi rotations take the rest.
#include "quadric.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace psq::detail {
namespace {

// The eigenvalues of the symmetric matrix `a`, largest first.
void eigenvalues(const double a[6], double w[3]) {
  const double p1 = a[1] * a[1] + a[2] * a[2] + a[4] * a[4];
  if (p1 == 0) {
    w[0] = a[0], w[1] = a[3], w[2] = a[5];
  } else {
    const double q = (a[0] + a[3] + a[5]) / 3;
    const double d0 = a[0] - q, d1 = a[3] - q, d2 = a[5] - q;
    const double p = std::sqrt((d0 * d0 + d1 * d1 + d2 * d2 + 2 * p1) / 6);
    // B = (A - qI) / p; its determinant / 2 is cos(3 phi).
    const double det = d0 * (d1 * d2 - a[4] * a[4]) - a[1] * (a[1] * d2 - a[4] * a[2]) + a[2] * (a[1] * a[4] - d1 * a[2]);
    const double r = std::min(1.0, std::max(-1.0, det / (2 * p * p * p)));
    const double phi = std::acos(r) / 3;
    const double third = 2.0943951023931954923;  // 2 pi / 3
    w[0] = q + 2 * p * std::cos(phi);
    w[2] = q + 2 * p * std::cos(phi + third);
    w[1] = 3 * q - w[0] - w[2];
  }
  if (w[0] < w[1]) std::swap(w[0], w[1]);
  if (w[1] < w[2]) std::swap(w[1], w[2]);
  if (w[0] < w[1]) std::swap(w[0], w[1]);
}

// The unit eigenvector of `a` for eigenvalue `l`, from the largest cross
// product of two rows of A - lI; false when none stands out (l is not
// apart from the other eigenvalues).
bool eigenvector(const double a[6], double l, double scale, double v[3]) {
  const double r[3][3] = {{a[0] - l, a[1], a[2]}, {a[1], a[3] - l, a[4]}, {a[2], a[4], a[5] - l}};
  double best = 0;
  for (int i = 0; i < 3; ++i) {
    const double* x = r[i];
    const double* y = r[(i + 1) % 3];
    const double c[3] = {x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]};
    const double n = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    if (n > best) {
      best = n;
      std::copy(c, c + 3, v);
    }
  }
  // The rows have norms up to `scale`; a cross product this small means
  // the rows are nearly parallel only because l is close to another
  // eigenvalue.
  if (!(best > 1e-24 * scale * scale * scale * scale)) return false;
  const double inv = 1 / std::sqrt(best);
  for (int k = 0; k < 3; ++k) v[k] *= inv;
  return true;
}

// The truncated solve by Jacobi's eigen-decomposition: every case.
void minimize_by_jacobi(const Quadric& q, const double r[3], double tolerance, double x[3]) {
  double w[3], v[3][3];
  symmetric_eigen(q.a, w, v);
  const double largest = std::fmax(std::fabs(w[0]), std::fmax(std::fabs(w[1]), std::fabs(w[2])));
  if (!(largest > 0) || !std::isfinite(largest)) return;
  for (int i = 0; i < 3; ++i) {
    if (!(w[i] > tolerance * largest)) continue;  // a quadric is positive semidefinite: small or negative is noise
    const double proj = (v[0][i] * r[0] + v[1][i] * r[1] + v[2][i] * r[2]) / w[i];
    for (int k = 0; k < 3; ++k) x[k] += proj * v[k][i];
  }
}

}  // namespace

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
  const double* a = q.a;
  // The residual r = -(A mean + b); the step from the mean is the sum over
  // the kept directions of (v_i . r / w_i) v_i.
  const double r[3] = {-(a[0] * mean[0] + a[1] * mean[1] + a[2] * mean[2] + q.b[0]),
                       -(a[1] * mean[0] + a[3] * mean[1] + a[4] * mean[2] + q.b[1]),
                       -(a[2] * mean[0] + a[4] * mean[1] + a[5] * mean[2] + q.b[2])};
  double w[3];
  eigenvalues(a, w);
  if (!(w[0] > 0) || !std::isfinite(w[0]) || !std::isfinite(r[0] + r[1] + r[2])) return;
  const double cut = tolerance * w[0];
  if (w[2] > cut) {
    // All three kept: A itself is well conditioned; s = A^-1 r by its
    // adjugate (the determinant is the product of the eigenvalues).
    const double c00 = a[3] * a[5] - a[4] * a[4], c01 = a[2] * a[4] - a[1] * a[5], c02 = a[1] * a[4] - a[2] * a[3];
    const double c11 = a[0] * a[5] - a[2] * a[2], c12 = a[1] * a[2] - a[0] * a[4], c22 = a[0] * a[3] - a[1] * a[1];
    const double det = a[0] * c00 + a[1] * c01 + a[2] * c02;
    if (det > 0 && std::isfinite(det)) {
      x[0] += (c00 * r[0] + c01 * r[1] + c02 * r[2]) / det;
      x[1] += (c01 * r[0] + c11 * r[1] + c12 * r[2]) / det;
      x[2] += (c02 * r[0] + c12 * r[1] + c22 * r[2]) / det;
      return;
    }
  } else if (w[1] <= cut) {
    // One kept (a flat cluster): its eigenvalue is a thousand times the
    // others, so its eigenvector is well defined.
    double v[3];
    if (eigenvector(a, w[0], w[0], v)) {
      const double proj = (v[0] * r[0] + v[1] * r[1] + v[2] * r[2]) / w[0];
      for (int k = 0; k < 3; ++k) x[k] += proj * v[k];
      return;
    }
  } else if (w[1] - w[2] > 1e-6 * w[0]) {
    // Two kept (a crease, a border, a cylinder): the dropped direction v is
    // apart from them; solve A in the plane orthogonal to it, which the
    // two kept eigenvectors span.
    double v[3];
    if (eigenvector(a, w[2], w[0], v)) {
      // An orthonormal basis u, t of the plane.
      const int axis = std::fabs(v[0]) < std::fabs(v[1]) ? (std::fabs(v[0]) < std::fabs(v[2]) ? 0 : 2)
                                                       : (std::fabs(v[1]) < std::fabs(v[2]) ? 1 : 2);
      const double e[3] = {axis == 0 ? 1.0 : 0.0, axis == 1 ? 1.0 : 0.0, axis == 2 ? 1.0 : 0.0};
      double u[3] = {v[1] * e[2] - v[2] * e[1], v[2] * e[0] - v[0] * e[2], v[0] * e[1] - v[1] * e[0]};
      const double un = 1 / std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
      for (double& c : u) c *= un;
      const double t[3] = {v[1] * u[2] - v[2] * u[1], v[2] * u[0] - v[0] * u[2], v[0] * u[1] - v[1] * u[0]};
      auto mul = [&](const double y[3], double out[3]) {
        out[0] = a[0] * y[0] + a[1] * y[1] + a[2] * y[2];
        out[1] = a[1] * y[0] + a[3] * y[1] + a[4] * y[2];
        out[2] = a[2] * y[0] + a[4] * y[1] + a[5] * y[2];
      };
      double au[3], at[3];
      mul(u, au);
      mul(t, at);
      const double m00 = u[0] * au[0] + u[1] * au[1] + u[2] * au[2];
      const double m01 = u[0] * at[0] + u[1] * at[1] + u[2] * at[2];
      const double m11 = t[0] * at[0] + t[1] * at[1] + t[2] * at[2];
      const double ru = u[0] * r[0] + u[1] * r[1] + u[2] * r[2];
      const double rt = t[0] * r[0] + t[1] * r[1] + t[2] * r[2];
      const double det = m00 * m11 - m01 * m01;
      if (det > 0 && std::isfinite(det)) {
        const double alpha = (m11 * ru - m01 * rt) / det, beta = (m00 * rt - m01 * ru) / det;
        for (int k = 0; k < 3; ++k) x[k] += alpha * u[k] + beta * t[k];
        return;
      }
    }
  }
  // Eigenvalues too close for a cross product, or a determinant that
  // underflowed: the general decomposition.
  minimize_by_jacobi(q, r, tolerance, x);
}

}  // namespace psq::detail
