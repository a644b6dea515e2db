// SPDX-License-Identifier: Apache-2.0
// Error quadrics (Garland and Heckbert, "Surface Simplification Using
// Quadric Error Metrics", 1997): the sum of weighted squared distances to a
// set of planes, Q(x) = x'Ax + 2b'x + c, with the total weight kept so that
// Q(x) / weight is a mean squared distance.
#ifndef PSQ_SIMPLIFY_QEM_QUADRIC_H_
#define PSQ_SIMPLIFY_QEM_QUADRIC_H_

#include <cmath>

namespace psq::detail {

struct QemQuadric {
  double a00 = 0, a01 = 0, a02 = 0, a11 = 0, a12 = 0, a22 = 0;
  double b0 = 0, b1 = 0, b2 = 0;
  double c = 0;
  double weight = 0;

  // Adds the plane n.x + d = 0 (n of unit length) with `w`.
  void add_plane(const double n[3], double d, double w) {
    a00 += w * n[0] * n[0];
    a01 += w * n[0] * n[1];
    a02 += w * n[0] * n[2];
    a11 += w * n[1] * n[1];
    a12 += w * n[1] * n[2];
    a22 += w * n[2] * n[2];
    b0 += w * n[0] * d;
    b1 += w * n[1] * d;
    b2 += w * n[2] * d;
    c += w * d * d;
    weight += w;
  }

  void add(const QemQuadric& q) {
    a00 += q.a00;
    a01 += q.a01;
    a02 += q.a02;
    a11 += q.a11;
    a12 += q.a12;
    a22 += q.a22;
    b0 += q.b0;
    b1 += q.b1;
    b2 += q.b2;
    c += q.c;
    weight += q.weight;
  }

  // Adds q scaled by s (its weight too).
  void add_scaled(const QemQuadric& q, double s) {
    a00 += s * q.a00;
    a01 += s * q.a01;
    a02 += s * q.a02;
    a11 += s * q.a11;
    a12 += s * q.a12;
    a22 += s * q.a22;
    b0 += s * q.b0;
    b1 += s * q.b1;
    b2 += s * q.b2;
    c += s * q.c;
    weight += s * q.weight;
  }

  double eval(const double x[3]) const {
    const double ax0 = a00 * x[0] + a01 * x[1] + a02 * x[2];
    const double ax1 = a01 * x[0] + a11 * x[1] + a12 * x[2];
    const double ax2 = a02 * x[0] + a12 * x[1] + a22 * x[2];
    return x[0] * ax0 + x[1] * ax1 + x[2] * ax2 + 2 * (b0 * x[0] + b1 * x[1] + b2 * x[2]) + c;
  }

  // Q(x), never negative (for a quadric of weight 1).
  double value(const double x[3]) const {
    const double e = eval(x);
    return e > 0 ? e : 0;
  }

  // The mean squared distance at x (never negative).
  double error(const double x[3]) const {
    const double e = eval(x);
    if (!(e > 0)) return 0;
    return weight > 0 ? e / weight : e;
  }

  // The x minimizing Q(x) + lambda |x - m|^2: solves (A + lambda I) x =
  // lambda m - b. The small pull towards m fixes the directions in which Q
  // hardly changes (a flat or straight neighbourhood), where the plain
  // minimum would be anywhere along a line or a plane; elsewhere it moves x
  // little. False when the system is singular all the same.
  bool minimum(double lambda, const double m[3], double x[3]) const {
    const double d00 = a00 + lambda, d11 = a11 + lambda, d22 = a22 + lambda;
    const double r0 = lambda * m[0] - b0, r1 = lambda * m[1] - b1, r2 = lambda * m[2] - b2;
    const double c00 = d11 * d22 - a12 * a12;
    const double c01 = a02 * a12 - a01 * d22;
    const double c02 = a01 * a12 - a02 * d11;
    const double det = d00 * c00 + a01 * c01 + a02 * c02;
    if (!(std::fabs(det) > 0)) return false;
    const double c11 = d00 * d22 - a02 * a02;
    const double c12 = a01 * a02 - d00 * a12;
    const double c22 = d00 * d11 - a01 * a01;
    const double inv = 1.0 / det;
    x[0] = inv * (c00 * r0 + c01 * r1 + c02 * r2);
    x[1] = inv * (c01 * r0 + c11 * r1 + c12 * r2);
    x[2] = inv * (c02 * r0 + c12 * r1 + c22 * r2);
    return std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2]);
  }

  // The t in [0, 1] minimizing Q(p + t d).
  double minimum_on_segment(const double p[3], const double d[3]) const {
    const double ad0 = a00 * d[0] + a01 * d[1] + a02 * d[2];
    const double ad1 = a01 * d[0] + a11 * d[1] + a12 * d[2];
    const double ad2 = a02 * d[0] + a12 * d[1] + a22 * d[2];
    const double dad = d[0] * ad0 + d[1] * ad1 + d[2] * ad2;
    // d'(Ap + b): half the derivative at t = 0.
    const double slope = p[0] * ad0 + p[1] * ad1 + p[2] * ad2 + b0 * d[0] + b1 * d[1] + b2 * d[2];
    if (!(dad > 0)) return slope < 0 ? 1.0 : 0.0;
    const double t = -slope / dad;
    return t < 0 ? 0.0 : (t > 1 ? 1.0 : t);
  }
};

}  // namespace psq::detail

#endif  // PSQ_SIMPLIFY_QEM_QUADRIC_H_
