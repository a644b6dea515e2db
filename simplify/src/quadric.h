// SPDX-License-Identifier: Apache-2.0
// Quadric error metrics (Garland and Heckbert 1997) and their robust
// minimizer (Lindstrom 2000, section 3.2): the pieces that simplify/'s
// filters share.
//
// A quadric is E(x) = x^T A x + 2 b^T x + c, the weighted sum of squared
// distances of x to a set of planes, kept in a frame of the caller's choice
// (a cell's corner, so that coordinates stay small and the sums lose no
// precision to large absolute positions).
#ifndef PSQ_SIMPLIFY_QUADRIC_H_
#define PSQ_SIMPLIFY_QUADRIC_H_

namespace psq::detail {

struct Quadric {
  // A, symmetric: a00 a01 a02 a11 a12 a22; then b and c.
  double a[6] = {0, 0, 0, 0, 0, 0};
  double b[3] = {0, 0, 0};
  double c = 0;

  void add(const Quadric& o) {
    for (int i = 0; i < 6; ++i) a[i] += o.a[i];
    for (int i = 0; i < 3; ++i) b[i] += o.b[i];
    c += o.c;
  }
  // Adds k (n.x + d)^2 for a plane n.x + d = 0 whose normal n need not be
  // of unit length: A += k n n^T, b += k d n, c += k d^2.
  void add_plane(const double n[3], double d, double k) {
    const double kn0 = k * n[0], kn1 = k * n[1], kn2 = k * n[2];
    a[0] += kn0 * n[0];
    a[1] += kn0 * n[1];
    a[2] += kn0 * n[2];
    a[3] += kn1 * n[1];
    a[4] += kn1 * n[2];
    a[5] += kn2 * n[2];
    b[0] += kn0 * d;
    b[1] += kn1 * d;
    b[2] += kn2 * d;
    c += k * d * d;
  }
  double error(const double x[3]) const;
};

// The eigenvalues w and orthonormal eigenvectors (columns of v, v[row][col])
// of the symmetric 3x3 matrix `a` (in Quadric's order), by cyclic Jacobi
// rotations.
void symmetric_eigen(const double a[6], double w[3], double v[3][3]);

// The minimizer of `q` nearest `mean` (Lindstrom 2000): A x = -b solved in
// A's eigenbasis, directions whose eigenvalue is below `tolerance` times the
// largest left at the mean's coordinate, so that a singular or nearly
// singular quadric (a flat or a cylindrical region) gives the point of its
// minimal set closest to the mean instead of an arbitrary far one. A zero
// quadric gives the mean. The common cases (all, one or two directions
// kept, apart from the dropped ones) take closed forms; the rest Jacobi's
// decomposition (symmetric_eigen); both give the same point to about
// 1e-10 of the step.
void minimize_quadric(const Quadric& q, const double mean[3], double tolerance, double x[3]);

}  // namespace psq::detail

#endif  // PSQ_SIMPLIFY_QUADRIC_H_
