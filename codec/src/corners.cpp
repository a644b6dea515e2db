// SPDX-License-Identifier: Apache-2.0
// codec/src/corners.cpp: corner attributes (spec/psq-format.md 8.5),
// normals and texture coordinates that differ between the corners at one
// vertex (a seam of the texture, a crease). The positions stay welded, as
// in Isenburg and Snoeyink, "Compressing texture coordinates with selective
// linear predictions" (CGI 2003) and Draco's attribute seams: each vertex
// keeps the distinct values of its corners so far, and a corner either
// takes one of them (a symbol, most recent first) or brings a new value,
// predicted from the triangle's corners whose values are known; texture
// coordinates by where the corner lies beside the other two in space,
// carried into the texture with the orientation seen last.
#include <algorithm>
#include <cmath>
#include <string>

#include "attributes.h"
#include "container.h"
#include "geometry.h"

namespace psq {
namespace codec {

Status AttributeCoder::split_face(const PropertyValues& in, uint64_t face, PropertyValues* columns,
                                  int32_t* cq) const {
  columns->clear();
  const int cd = corner_dims();
  size_t at = 0;
  for (size_t i = 0; i < face_.size(); ++i) {
    const Status mismatch(ErrorCode::kBadValue, "face property values do not match the schema");
    if (at >= in.size()) return mismatch;
    size_t n = 1;
    if (face_[i].is_list) {
      if (!(in[at] >= 0 && in[at] < static_cast<double>(in.size()))) return mismatch;
      n += static_cast<size_t>(in[at]);
    }
    if (in.size() - at < n) return mismatch;
    const int ai = face_role_[i];
    if (ai < 0) {
      columns->insert(columns->end(), in.begin() + static_cast<std::ptrdiff_t>(at),
                      in.begin() + static_cast<std::ptrdiff_t>(at + n));
      at += n;
      continue;
    }
    const Corner& a = corner_[static_cast<size_t>(ai)];
    const bool normal = a.kind == CodedAttribute::Kind::kCornerNormal;
    const size_t arity = normal ? 3 : 2;
    if (n - 1 != 3 * arity)
      return Status(ErrorCode::kBadValue, "face " + std::to_string(face) + ": " + face_[i].name + " holds " +
                                              std::to_string(n - 1) + " values, not " + std::to_string(3 * arity) +
                                              " (keep it as a column: " + (normal ? "normal" : "uv") + " bits 0)");
    for (int j = 0; j < 3; ++j) {
      const double* v = &in[at + 1 + static_cast<size_t>(j) * arity];
      int32_t* q = cq + j * cd + 2 * ai;
      if (normal) {
        if (!octahedral_encode(v, (1 << (a.bits - 1)) - 1, &q[0], &q[1]))
          return Status(ErrorCode::kBadValue, "face " + std::to_string(face) + ": a corner normal is not finite "
                                                                               "(keep normals exact: normal bits 0)");
        continue;
      }
      for (int d = 0; d < 2; ++d) {
        const double g = std::ldexp(v[d], a.bits);
        if (!(std::fabs(g) < 2147483647.0))
          return Status(ErrorCode::kBadValue, "face " + std::to_string(face) +
                                                  ": corner texture coordinate not finite or beyond the grid of " +
                                                  std::to_string(a.bits) + " bits (keep them exact: uv bits 0)");
        q[d] = static_cast<int32_t>(std::llround(g));
      }
    }
    at += n;
  }
  return Status();
}

void AttributeCoder::merge_face(const PropertyValues& columns, const int32_t* cq, PropertyValues* out) const {
  out->clear();
  const int cd = corner_dims();
  size_t at = 0;
  for (size_t i = 0; i < face_.size(); ++i) {
    const int ai = face_role_[i];
    if (ai < 0) {
      size_t n = 1;
      if (face_[i].is_list) n += static_cast<size_t>(columns[at]);
      out->insert(out->end(), columns.begin() + static_cast<std::ptrdiff_t>(at),
                  columns.begin() + static_cast<std::ptrdiff_t>(at + n));
      at += n;
      continue;
    }
    const Corner& a = corner_[static_cast<size_t>(ai)];
    const bool normal = a.kind == CodedAttribute::Kind::kCornerNormal;
    const bool single = face_[i].type == ScalarType::kFloat32;
    out->push_back(normal ? 9 : 6);
    for (int j = 0; j < 3; ++j) {
      const int32_t* q = cq + j * cd + 2 * ai;
      double v[3];
      if (normal) {
        octahedral_decode(q[0], q[1], (1 << (a.bits - 1)) - 1, v);
      } else {
        for (int d = 0; d < 2; ++d) v[d] = std::ldexp(static_cast<double>(q[d]), -a.bits);
      }
      for (int d = 0; d < (normal ? 3 : 2); ++d) out->push_back(single ? round_to_float(v[d]) : v[d]);
    }
  }
}

AttributeCoder::Wedges& AttributeCoder::wedges(uint32_t slot, size_t a) {
  // Slots stay below the boundary limit (spec 6.1.1), as grow() assumes.
  thread_local Wedges none;
  if (slot >= (1u << 28)) return none = Wedges();
  const size_t need = (static_cast<size_t>(slot) + 1) * corner_.size();
  if (wedges_.size() < need) wedges_.resize(std::max(need, 2 * wedges_.size()));
  return wedges_[static_cast<size_t>(slot) * corner_.size() + a];
}

// Spec 8.5: the triangle's corners, then the corner normals now due.
const char* AttributeCoder::code_corners(const AttributeRecord& r, Coding& code) {
  settled_corners_.clear();
  pending_corners_ = 0;
  if ((r.triangle && !corner_walk(r, code)) || (late_corners_ && !corners_due(r, code)))
    return code.why ? code.why : "attribute data is corrupt";
  return nullptr;
}

// Spec 8.5: the prediction of texture coordinate j's new value from the
// triangle's corners known so far (`known`, values `x`): rule 0 with both
// others known, 1 with one, 2 with none.
void AttributeCoder::predict_texcoord(const AttributeRecord& r, const Corner& a, int j, const bool* known,
                                      int32_t (*x)[2], int* rule, int64_t* pred, int* extent) const {
  const int p = (j + 1) % 3, q = (j + 2) % 3;
  *rule = 2 - static_cast<int>(known[p]) - static_cast<int>(known[q]);
  extent[0] = extent[1] = 0;
  pred[0] = a.last[0];
  pred[1] = a.last[1];
  if (*rule == 1) {
    const int k = known[p] ? p : q;
    pred[0] = x[k][0];
    pred[1] = x[k][1];
    return;
  }
  if (*rule == 2) return;
  const int32_t* A = x[p];
  const int32_t* B = x[q];
  for (int d = 0; d < 2; ++d) {
    pred[d] = (int64_t{A[d]} + B[d]) >> 1;
    extent[d] = bit_length64(static_cast<uint64_t>(A[d] > B[d] ? int64_t{A[d]} - B[d] : int64_t{B[d]} - A[d]));
  }
  if (r.pos[0] == nullptr) return;
  // Where corner j lies beside the edge from p to q in space: its foot on
  // the edge and its distance from it, in edge lengths (as 8.3), carried
  // to the edge in the texture on the side the orientation gives.
  double t, h;
  if (beside_edge(r, j, &t, &h)) texture_point(A, B, t, a.orientation * h, a.comp[0], pred);
}

// Spec 8.5: for each corner attribute, the corners in order of their
// vertices' dense indices: a wedge symbol for each corner whose vertex
// has values; then, in the same order, the new values (a normal's when it
// settles, below); then a normal's fan takes the triangle's area vector,
// and the finalized corners' waiting normals settle.
bool AttributeCoder::corner_walk(const AttributeRecord& r, Coding& code) {
  const int cd = corner_dims();
  int order[3] = {0, 1, 2};
  std::sort(order, order + 3, [&](int a, int b) { return r.v[a] < r.v[b]; });
  // The slots' values grow first: the pointers below must stay valid.
  wedges(std::max({r.c[0], r.c[1], r.c[2]}), corner_.size() - 1);
  for (size_t ai = 0; ai < corner_.size(); ++ai) {
    Corner& a = corner_[ai];
    const bool normal = a.kind == CodedAttribute::Kind::kCornerNormal;
    int32_t x[3][2];
    bool known[3] = {false, false, false};
    Wedges* w[3];
    Wedge* taken[3];
    for (int k : order) {
      Wedges& W = *(w[k] = &wedges(r.c[k], ai));
      int32_t* mine = r.corners + k * cd + 2 * ai;
      if (r.new_mask >> k & 1) {
        // A finalized vertex's normals were settled (step 4); a slot's
        // earlier values wait no more.
        for (int i = 0; i < W.n; ++i) release(W.w[i]);
        W.n = 0;
      }
      if (W.n == 0) continue;
      // The encoder's symbol (the decoder's is decoded over it).
      uint32_t s = kNewWedge;
      for (int i = 0; i < W.n && s == kNewWedge; ++i)
        if (W.w[i].v[0] == mine[0] && W.w[i].v[1] == mine[1]) s = static_cast<uint32_t>(i);
      const int ctx = std::min(W.n, 3) - 1;
      if (!code.symbol(wedge_table(ai, ctx), a.wedge[ctx], &s)) return false;
      if (s == kNewWedge) continue;
      if (s >= static_cast<uint32_t>(W.n)) return code.why = "a corner takes a value its vertex does not have", false;
      std::rotate(W.w, W.w + s, W.w + s + 1);
      Wedge& t = *(taken[k] = &W.w[0]);
      x[k][0] = mine[0] = t.v[0];
      x[k][1] = mine[1] = t.v[1];
      known[k] = true;
    }
    for (int k : order) {
      if (known[k]) continue;
      Wedges& W = *w[k];
      if (W.n == kMaxWedges) {
        // The least recent value leaves; a normal still waiting settles.
        Wedge& out = W.w[kMaxWedges - 1];
        if (out.wait && !corner_settle(code, ai, out, 1)) return false;
        --W.n;
      }
      std::rotate(W.w, W.w + W.n, W.w + W.n + 1);
      ++W.n;
      Wedge& t = *(taken[k] = &W.w[0]);
      int32_t* mine = r.corners + k * cd + 2 * ai;
      t.v[0] = mine[0];  // the encoder's value; the decoder's comes below
      t.v[1] = mine[1];
      t.wait = 0;
      known[k] = true;
      if (normal) {
        uint32_t at;
        if (free_waiters_.empty()) {
          at = static_cast<uint32_t>(waiters_.size());
          waiters_.emplace_back();
        } else {
          at = free_waiters_.back();
          free_waiters_.pop_back();
        }
        Waiter& g = waiters_[at];
        g.serial = serial_++;
        g.n[0] = g.n[1] = g.n[2] = 0;
        g.refs.clear();
        t.wait = at + 1;
        corner_waiting_.push_back(CornerWaiting{r.c[k], static_cast<uint32_t>(ai), g.serial, records_});
        continue;
      }
      int rule, extent[2];
      int64_t pred[2];
      predict_texcoord(r, a, k, known, x, &rule, pred, extent);
      int longest = 0;
      for (int d = 0; d < 2; ++d) {
        const int ctx = attribute_context(rule == 0 ? 0 : 1, d == 0, extent[d], longest);
        int length;
        if (!code.residual(corner_table(ai, rule, d, ctx),
                           a.models[static_cast<size_t>((rule * 2 + d) * kLengthContexts + ctx)], a.comp[d], pred[d],
                           &mine[d], &length))
          return false;
        longest = std::max(longest, length);
      }
      x[k][0] = t.v[0] = a.last[0] = mine[0];
      x[k][1] = t.v[1] = a.last[1] = mine[1];
    }
    if (!normal) {
      // The orientation of the triangle in the texture, exactly.
      const __int128 area = static_cast<__int128>(int64_t{x[1][0]} - x[0][0]) * (int64_t{x[2][1]} - x[0][1]) -
                            static_cast<__int128>(int64_t{x[1][1]} - x[0][1]) * (int64_t{x[2][0]} - x[0][0]);
      if (area != 0) a.orientation = area > 0 ? 1 : -1;
      continue;
    }
    double n[3];
    area_vector(r, n);
    for (int k = 0; k < 3; ++k) {
      const Wedge& t = *taken[k];
      if (!t.wait) continue;
      Waiter& g = waiters_[t.wait - 1];
      for (int i = 0; i < 3; ++i) g.n[i] = g.n[i] + n[i];
      g.refs.push_back(r.event * 4 + static_cast<uint64_t>(k));
      ++pending_corners_;
    }
    for (int k : order) {
      if (!(r.final_mask >> k & 1)) continue;
      Wedges& W = *w[k];
      for (int i = 0; i < W.n; ++i)
        if (W.w[i].wait && !corner_settle(code, ai, W.w[i], 0)) return false;
    }
  }
  return true;
}

// Spec 8.5: a corner normal predicted by the direction of its fan's area
// vector, else by the normal coded before; rule 3 for a finalized vertex,
// 4 for the others (both with the contexts of 8.3's kind 1).
bool AttributeCoder::corner_settle(Coding& code, size_t ai, Wedge& w, int kind) {
  Corner& a = corner_[ai];
  Waiter& g = waiters_[w.wait - 1];
  const int32_t c = (int32_t{1} << (a.bits - 1)) - 1;
  int64_t pred[2] = {a.last[0], a.last[1]};
  octahedral_round(g.n, c, &pred[0], &pred[1]);  // a zero sum keeps the normal before
  const int rule = 3 + kind;
  int longest = 0;
  for (int d = 0; d < 2; ++d) {
    const int ctx = attribute_context(1, d == 0, 0, longest);
    int length;
    if (!code.residual(corner_table(ai, rule, d, ctx), a.models[static_cast<size_t>((rule * 2 + d) * kLengthContexts + ctx)],
                       a.comp[d], pred[d], &w.v[d], &length))
      return false;
    longest = std::max(longest, length);
  }
  a.last[0] = w.v[0];
  a.last[1] = w.v[1];
  for (uint64_t ref : g.refs)
    settled_corners_.push_back(
        SettledCorner{ref >> 2, static_cast<int>(ref & 3), static_cast<int>(ai), {w.v[0], w.v[1]}});
  release(w);
  return true;
}

void AttributeCoder::release(Wedge& w) {
  if (w.wait == 0) return;
  waiters_[w.wait - 1].refs.clear();
  free_waiters_.push_back(w.wait - 1);
  w.wait = 0;
}

// Spec 8.5: a corner normal waits at most kMaxNormalWait records after
// the one that brought it, and none past the end of its chunk.
bool AttributeCoder::corners_due(const AttributeRecord& r, Coding& code) {
  while (!corner_waiting_.empty() &&
         (r.flush || corner_waiting_.front().record + kMaxNormalWait <= records_)) {
    const CornerWaiting cw = corner_waiting_.front();
    corner_waiting_.pop_front();
    Wedges& W = wedges(cw.slot, cw.attribute);
    for (int i = 0; i < W.n; ++i)
      if (W.w[i].wait && waiters_[W.w[i].wait - 1].serial == cw.serial &&
          !corner_settle(code, cw.attribute, W.w[i], 1))
        return false;
  }
  return true;
}

void AttributeCoder::patch_face(PropertyValues* values, const SettledCorner& s) const {
  size_t at = 0;
  for (size_t i = 0; i < face_.size(); ++i) {
    if (face_role_[i] == s.attribute) {
      double v[3];
      octahedral_decode(s.q[0], s.q[1], (1 << (corner_[static_cast<size_t>(s.attribute)].bits - 1)) - 1, v);
      const bool single = face_[i].type == ScalarType::kFloat32;
      for (int d = 0; d < 3; ++d) (*values)[at + 1 + static_cast<size_t>(s.corner) * 3 + static_cast<size_t>(d)] = single ? round_to_float(v[d]) : v[d];
      return;
    }
    at += face_[i].is_list ? 1 + static_cast<size_t>((*values)[at]) : 1;
  }
}

}  // namespace codec
}  // namespace psq
