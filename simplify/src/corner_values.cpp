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
// (within twice its length of its midpoint), and a chart that is flat
// over the triangle gets exact values; smooth normals and charts on a
// curved surface are followed better than by clamping to the triangle
// (on the tests' sphere, normals 16 times closer). A degenerate triangle
// (or a place far past a thin one) gives the point of edge a-b nearest
// to p.
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
  if (det > 1e-6 * bb * cc) {  // angles above 0.001 radians
    w[1] = (pb * cc - pc * bc) / det;
    w[2] = (pc * bb - pb * bc) / det;
    w[0] = 1 - w[1] - w[2];
    // Far past the triangle, a sliver's plane says little: the edge then.
    if (std::min({w[0], w[1], w[2]}) >= -0.5 && std::max({w[0], w[1], w[2]}) <= 1.5) return;
  }
  w[1] = bb > 0 ? std::min(1.0, std::max(0.0, pb / bb)) : 0;
  w[2] = 0;
  w[0] = 1 - w[1];
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
  for (size_t i = 0; i < list.property; ++i) {
    if (at >= fv.size()) return kNoValue;
    if (!is_list_[i]) {
      ++at;
      continue;
    }
    const double count = fv[at];
    if (!(count >= 0 && count <= static_cast<double>(fv.size() - at - 1)) || count != std::floor(count)) return kNoValue;
    at += 1 + static_cast<size_t>(count);
  }
  const size_t values = 3 * static_cast<size_t>(list.arity);
  if (at >= fv.size() || fv[at] != static_cast<double>(values) || fv.size() - at - 1 < values) return kNoValue;
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
    double w[3];  // p's weights in the triangle
  } side[2];
  int sides = 0;
  side[sides++] = {keep_start ? TriangleBuffer::next(h) : h, keep_start ? h : TriangleBuffer::next(h),
                   TriangleBuffer::prev(h), {0, 0, 0}};
  const uint32_t o = b.opposite(h);
  if (o < TriangleBuffer::kOpen)
    side[sides++] = {keep_start ? o : TriangleBuffer::next(o), keep_start ? TriangleBuffer::next(o) : o,
                     TriangleBuffer::prev(o), {0, 0, 0}};
  const uint32_t keep = b.vertex_of(side[0].keep), gone = b.vertex_of(side[0].gone);
  const double* pk = b.position(keep);
  const double* pg = b.position(gone);
  double edge = 0, moved = 0;
  for (int i = 0; i < 3; ++i) {
    edge += (pg[i] - pk[i]) * (pg[i] - pk[i]);
    moved += (p[i] - pk[i]) * (p[i] - pk[i]);
  }
  const bool keep_stays = moved <= 1e-12 * edge;
  for (int s = 0; s < sides; ++s) plane_weights(pg, pk, b.position(b.vertex_of(side[s].third)), p, side[s].w);
  for (uint32_t v : {gone, keep}) {
    for (uint32_t c = b.first_corner(v); c != TriangleBuffer::kNone; c = b.next_corner(c)) {
      const uint32_t t = c / 3;
      if (t == side[0].gone / 3 || (sides == 2 && t == side[1].gone / 3)) continue;
      for (size_t l = 0; l < lists_.size(); ++l) {
        // The sides whose corner at v has c's value: c's chart.
        bool match[2] = {false, false};
        for (int s = 0; s < sides; ++s) match[s] = same_value(b, l, c, v == gone ? side[s].gone : side[s].keep);
        if (!match[0] && !match[1]) {
          if (v == keep && keep_stays) continue;
          return false;  // a seam across the edge would tear
        }
        int s = match[0] ? 0 : 1;
        if (match[0] && match[1]) {
          // Both sides: one chart, unless they part at the edge's other
          // end (a seam that ends at v, which its corners cannot follow).
          const uint32_t other0 = v == gone ? side[0].keep : side[0].gone;
          const uint32_t other1 = v == gone ? side[1].keep : side[1].gone;
          if (!same_value(b, l, other0, other1)) return false;
          // The side whose triangle p lies over.
          if (std::min({side[1].w[0], side[1].w[1], side[1].w[2]}) > std::min({side[0].w[0], side[0].w[1], side[0].w[2]}))
            s = 1;
        }
        const size_t at = value_index(b.face_values(t), l, c % 3);
        if (at == kNoValue) continue;
        const List& list = lists_[l];
        Change change{t, at, list.arity, {0, 0, 0}};
        if (v == keep && keep_stays) {
          const PropertyValues& fv = b.face_values(t);
          std::copy(fv.begin() + static_cast<std::ptrdiff_t>(at), fv.begin() + static_cast<std::ptrdiff_t>(at) + list.arity,
                    change.value);
        } else {
          const Side& e = side[s];
          const uint32_t corner[3] = {e.gone, e.keep, e.third};
          for (int k = 0; k < 3; ++k) {
            if (e.w[k] == 0) continue;  // (a non-finite value there stays out)
            const PropertyValues& fv = b.face_values(corner[k] / 3);
            const size_t i = value_index(fv, l, corner[k] % 3);
            if (i == kNoValue) return false;  // a triangle without values beside one with them
            for (int j = 0; j < list.arity; ++j) change.value[j] += e.w[k] * fv[i + j];
          }
          if (list.normal) {
            const double n = std::sqrt(dot3(change.value, change.value));
            if (!(n > 0)) return false;
            for (int j = 0; j < 3; ++j) change.value[j] /= n;
          }
          for (int j = 0; j < list.arity; ++j)
            if (!std::isfinite(change.value[j])) return false;
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

void CornerValues::fill_cap(TriangleBuffer* b, uint32_t t) const {
  for (uint32_t k = 0; k < 3; ++k) {
    const uint32_t c = 3 * t + k;
    const uint32_t o = b->opposite(c);
    if (o >= TriangleBuffer::kOpen) continue;
    // The edge of c runs from c's vertex; the corner across it that ends
    // there is next(o).
    const uint32_t from = TriangleBuffer::next(o);
    for (size_t l = 0; l < lists_.size(); ++l) {
      const size_t at = value_index(b->face_values(t), l, k);
      const size_t src = value_index(b->face_values(from / 3), l, from % 3);
      if (at == kNoValue || src == kNoValue) continue;
      const PropertyValues& values = b->face_values(from / 3);  // another triangle's: not fv
      PropertyValues& fv = *b->mutable_face_values(t);
      for (int j = 0; j < lists_[l].arity; ++j) fv[at + static_cast<size_t>(j)] = values[src + static_cast<size_t>(j)];
    }
  }
}

}  // namespace psq::detail
