// SPDX-License-Identifier: Apache-2.0
// simplify/src/corner_values.cpp: corner texture coordinates and normals
// through edge collapses (corner_values.h says how and why).
#include "corner_values.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace psq::detail {
namespace {

double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// Barycentric weights, with respect to triangle (a, b, c), of p projected
// into the triangle's plane: the chart's values there, extended linearly
// past the triangle's sides. A collapse places its vertex near the edge
// (within the edge's length of its midpoint), and a chart that is flat
// over the triangle gets exact values; smooth normals and charts on a
// curved surface are followed better than by clamping to the triangle
// (on the tests' sphere, normals 16 times closer). A degenerate triangle
// gives the point of edge a-b nearest to p.
void plane_weights(const double a[3], const double b[3], const double c[3], const double p[3], double w[3]) {
  double ab[3], ac[3], ap[3];
  for (int i = 0; i < 3; ++i) {
    ab[i] = b[i] - a[i];
    ac[i] = c[i] - a[i];
    ap[i] = p[i] - a[i];
  }
  const double bb = dot3(ab, ab), bc = dot3(ab, ac), cc = dot3(ac, ac);
  const double pb = dot3(ap, ab), pc = dot3(ap, ac);
  const double det = bb * cc - bc * bc;
  if (det > 1e-12 * bb * cc) {
    w[1] = (pb * cc - pc * bc) / det;
    w[2] = (pc * bb - pb * bc) / det;
  } else {
    w[1] = bb > 0 ? std::min(1.0, std::max(0.0, pb / bb)) : 0;
    w[2] = 0;
  }
  w[0] = 1 - w[1] - w[2];
}

}  // namespace

bool CornerValues::init(const MeshSchema& schema) {
  lists_.clear();
  is_list_.clear();
  for (size_t i = 0; i < schema.face_properties.size(); ++i) {
    const Property& p = schema.face_properties[i];
    is_list_.push_back(p.is_list);
    const bool real = p.type == ScalarType::kFloat32 || p.type == ScalarType::kFloat64;
    if (!p.is_list || !real) continue;
    if (p.name == "corner_uv") lists_.push_back({i, 2, false});
    if (p.name == "corner_normals") lists_.push_back({i, 3, true});
  }
  return active();
}

size_t CornerValues::value_index(const PropertyValues& fv, size_t l, uint32_t k) const {
  const List& list = lists_[l];
  size_t at = 0;
  for (size_t i = 0; i < list.property && at < fv.size(); ++i)
    at += is_list_[i] ? 1 + static_cast<size_t>(fv[at]) : 1;
  if (at >= fv.size() || fv[at] != 3.0 * list.arity) return kNoValue;  // not one value a corner
  return at + 1 + k * static_cast<size_t>(list.arity);
}

bool CornerValues::same_value(const TriangleBuffer& b, size_t l, uint32_t c, uint32_t d) const {
  const PropertyValues& fc = b.face_values(c / 3);
  const PropertyValues& fd = b.face_values(d / 3);
  const size_t ic = value_index(fc, l, c % 3), id = value_index(fd, l, d % 3);
  if (ic == kNoValue || id == kNoValue) return ic == id;
  for (int i = 0; i < lists_[l].arity; ++i)
    if (fc[ic + i] != fd[id + i]) return false;
  return true;
}

bool CornerValues::seam_vertex(const TriangleBuffer& b, uint32_t v) const {
  const uint32_t first = b.first_corner(v);
  for (size_t l = 0; l < lists_.size(); ++l)
    for (uint32_t c = b.next_corner(first); c != TriangleBuffer::kNone; c = b.next_corner(c))
      if (!same_value(b, l, first, c)) return true;
  return false;
}

bool CornerValues::seam_edge(const TriangleBuffer& b, uint32_t h) const {
  const uint32_t o = b.opposite(h);
  if (o >= TriangleBuffer::kOpen) return false;
  // h runs from x to y, o from y to x: compare at x and at y.
  for (size_t l = 0; l < lists_.size(); ++l)
    if (!same_value(b, l, h, TriangleBuffer::next(o)) || !same_value(b, l, TriangleBuffer::next(h), o)) return true;
  return false;
}

bool CornerValues::plan(const TriangleBuffer& b, uint32_t h, bool keep_start, const double p[3]) {
  changes_.clear();
  // The collapsed triangles: the corners of gone, keep and the third vertex.
  struct Side {
    uint32_t gone, keep, third;
    bool weighed;
    double w[3];
  } side[2];
  int sides = 0;
  side[sides++] = {keep_start ? TriangleBuffer::next(h) : h, keep_start ? h : TriangleBuffer::next(h),
                   TriangleBuffer::prev(h), false, {0, 0, 0}};
  const uint32_t o = b.opposite(h);
  if (o < TriangleBuffer::kOpen)
    side[sides++] = {keep_start ? o : TriangleBuffer::next(o), keep_start ? TriangleBuffer::next(o) : o,
                     TriangleBuffer::prev(o), false, {0, 0, 0}};
  const uint32_t keep = b.vertex_of(side[0].keep), gone = b.vertex_of(side[0].gone);
  const double* pk = b.position(keep);
  const double* pg = b.position(gone);
  double edge = 0, moved = 0;
  for (int i = 0; i < 3; ++i) {
    edge += (pg[i] - pk[i]) * (pg[i] - pk[i]);
    moved += (p[i] - pk[i]) * (p[i] - pk[i]);
  }
  const bool keep_stays = moved <= 1e-12 * edge;
  for (uint32_t v : {gone, keep}) {
    for (uint32_t c = b.first_corner(v); c != TriangleBuffer::kNone; c = b.next_corner(c)) {
      const uint32_t t = c / 3;
      if (t == side[0].gone / 3 || (sides == 2 && t == side[1].gone / 3)) continue;
      for (size_t l = 0; l < lists_.size(); ++l) {
        int s = 0;
        while (s < sides && !same_value(b, l, c, v == gone ? side[s].gone : side[s].keep)) ++s;
        if (s == sides) {
          if (v == keep && keep_stays) continue;
          return false;  // a seam across the edge would tear
        }
        const size_t at = value_index(b.face_values(t), l, c % 3);
        if (at == kNoValue) continue;
        Side& e = side[s];
        if (!e.weighed) {
          plane_weights(b.position(gone), b.position(keep), b.position(b.vertex_of(e.third)), p, e.w);
          e.weighed = true;
        }
        const List& list = lists_[l];
        Change change{t, at, list.arity, {0, 0, 0}};
        const uint32_t corner[3] = {e.gone, e.keep, e.third};
        for (int k = 0; k < 3; ++k) {
          const PropertyValues& fv = b.face_values(corner[k] / 3);
          const size_t i = value_index(fv, l, corner[k] % 3);
          if (i == kNoValue) return false;  // a triangle without values beside one with them
          for (int j = 0; j < list.arity; ++j) change.value[j] += e.w[k] * fv[i + j];
        }
        if (v == keep && keep_stays) {
          const PropertyValues& fv = b.face_values(t);
          for (int j = 0; j < list.arity; ++j) change.value[j] = fv[at + j];
        } else if (list.normal) {
          const double n = std::sqrt(dot3(change.value, change.value));
          if (n > 0)
            for (int j = 0; j < 3; ++j) change.value[j] /= n;
        }
        changes_.push_back(change);
      }
    }
  }
  return true;
}

void CornerValues::apply(TriangleBuffer* b) const {
  for (const Change& c : changes_) {
    PropertyValues& fv = *b->mutable_face_values(c.triangle);
    std::copy(c.value, c.value + c.arity, fv.begin() + static_cast<std::ptrdiff_t>(c.at));
  }
}

}  // namespace psq::detail
