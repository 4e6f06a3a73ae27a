// Setup stage, eight faces at a time: the same records as setup.cpp's one-face path, lane by
// lane; faces that need clipping go to setup_face.
#include "setup.hpp"

#include "dispatch.hpp"
#include "lanes.hpp"

#include <cstddef>

namespace sr {

namespace {

using namespace simd;

// One corner of eight faces: the ProjectedVertex records as fields, one face per lane.
struct CornerLanes {
  i8 x, y;
  f8 dx, dy, key, inv_w;
  i8 outcode;
};

SR_INLINE CornerLanes gather_corner(const ProjectedVertex* vertices, const int32_t* face_index,
                                    int corner) {
  i8 rows[8];
  for (int j = 0; j < 8; ++j) rows[j] = load<i8>(vertices + face_index[3 * j + corner]);
  transpose8(rows);
  return {rows[0], rows[1], f8(rows[2]), f8(rows[3]), f8(rows[4]), f8(rows[5]),
          rows[6] & splat(0xff)};
}

// Faces [f, f + 8) at once: setup_triangle and plane_keys_over_area lane by lane, with the same
// IEEE operations in the same order (area2, a product of 25-bit integers, is exact in double),
// so the same records. Integer tests (culling, the empty bounding box) come first for all eight;
// the floating-point work only if some face survives. Faces with a vertex outside a plane or not
// finite go to setup_face, in order, so records keep primitive order.
SR_INLINE void setup_eight(const SetupParams& params, std::size_t f, SetupChunk& out) {
  const int32_t* face_index = &params.mesh->faces[f].x;
  CornerLanes v[3];
  for (int k = 0; k < 3; ++k) v[k] = gather_corner(params.vertices, face_index, k);
  const unsigned special = mask_bits((v[0].outcode | v[1].outcode | v[2].outcode) != 0);

  const i8 ex1 = v[1].x - v[0].x, ey1 = v[1].y - v[0].y;
  const i8 ex2 = v[2].x - v[0].x, ey2 = v[2].y - v[0].y;
  d4 area2[2];
  unsigned negative = 0, nonzero = 0;
  for (int h = 0; h < 2; ++h) {
    area2[h] = wide(ex1, h) * wide(ey2, h) - wide(ey1, h) * wide(ex2, h);
    negative |= mask_bits(l4(area2[h] < 0.0)) << (4 * h);
    nonzero |= mask_bits(l4(area2[h] != 0.0)) << (4 * h);
  }
  const unsigned front = negative ^ (params.transform->mirrored ? 0xffu : 0u);
  const unsigned facing = params.cull == Cull::Back ? front
                          : params.cull == Cull::Front ? ~front : 0xffu;
  const i8 x_min = min(min(v[0].x, v[1].x), v[2].x), x_max = max(max(v[0].x, v[1].x), v[2].x);
  const i8 y_min = min(min(v[0].y, v[1].y), v[2].y), y_max = max(max(v[0].y, v[1].y), v[2].y);
  // The box of pixels with a sample in the triangle's box (setup.cpp, first_sample/last_sample).
  const SamplePattern& samples = params.viewport.samples;
  const i8 zero{};
  const i8 x0 = max((x_min + splat(kSubpixelOne - 1 - samples.max_x)) >> kSubpixelBits, zero);
  const i8 y0 = max((y_min + splat(kSubpixelOne - 1 - samples.max_y)) >> kSubpixelBits, zero);
  const i8 x1 = min((x_max - splat(samples.min_x)) >> kSubpixelBits, splat(params.viewport.width - 1));
  const i8 y1 = min((y_max - splat(samples.min_y)) >> kSubpixelBits, splat(params.viewport.height - 1));
  const unsigned nonempty = mask_bits((x0 <= x1) & (y0 <= y1));
  unsigned keep = ~special & nonzero & facing & nonempty & 0xffu;
  if ((keep | special) == 0) return;  // the common case in a dense mesh

  alignas(32) int32_t lane_x[3][8], lane_y[3][8], lane_box[4][8], lane_bias[3][8];
  alignas(32) float lane_key[3][8], lane_persp[3][8];
  alignas(32) float lane_q[3][3][8];  // params.exact_weights: ExactWeights::q
  alignas(32) double lane_area2[8];
  unsigned exact = 0;  // kExactDepth per lane
  if (keep != 0) {
    // Orient: vertices 1 and 2 swap where area2 < 0.
    const i8 swapped = (splat(int32_t(negative)) & i8{1, 2, 4, 8, 16, 32, 64, 128}) != zero;
    const CornerLanes* o[3] = {&v[0], &v[1], &v[2]};
    i8 ox[3], oy[3];
    f8 odx[3], ody[3], okey[3];
    for (int k = 0; k < 3; ++k) {
      const CornerLanes& a = *o[k];
      const CornerLanes& b = *o[k == 0 ? 0 : 3 - k];  // the vertex it swaps with
      ox[k] = select(swapped, b.x, a.x);
      oy[k] = select(swapped, b.y, a.y);
      odx[k] = select(swapped, b.dx, a.dx);
      ody[k] = select(swapped, b.dy, a.dy);
      okey[k] = select(swapped, b.key, a.key);
    }
    // The top-left rule, as in setup_triangle: bias 0 for top and left edges, else 1.
    i8 edge_dx[3], edge_dy[3], bias[3];
    for (int k = 0; k < 3; ++k) {
      const int a = kEdgeStart[k], b = kEdgeEnd[k];
      edge_dx[k] = ox[b] - ox[a];
      edge_dy[k] = oy[b] - oy[a];
      const i8 top_left = (edge_dy[k] < zero) | ((edge_dy[k] == zero) & (edge_dx[k] > zero));
      bias[k] = top_left + splat(1);
    }
    // A box holding one or two pixels: test their samples (covers_box_samples); here for a
    // pattern of one sample, and left to the tile pass for more.
    const i8 few = (x1 - x0) + (y1 - y0) <= splat(1);
    if (samples.count == 1 && (keep & mask_bits(few))) {
      const i8 sx = splat(samples.x[0]), sy = splat(samples.y[0]);
      i8 covered = zero;
      for (int s = 0; s < 2; ++s) {
        const i8 cx = ((s == 0 ? x0 : x1) << kSubpixelBits) + sx;
        const i8 cy = ((s == 0 ? y0 : y1) << kSubpixelBits) + sy;
        i8 inside = ~zero;
        for (int k = 0; k < 3; ++k) {
          const int a = kEdgeStart[k];
          // Exact in 32 bits where few samples bound the triangle (spans < 3 px); lanes where
          // they do not wrap harmlessly (unsigned) and are not used.
          const u8 e = u8(edge_dx[k]) * u8(cy - oy[a]) - u8(edge_dy[k]) * u8(cx - ox[a]);
          inside &= i8(e) >= bias[k];
        }
        covered |= inside;
      }
      keep &= ~mask_bits(few & ~covered);
    }
    if (keep != 0) {
      f8 oinv_w[3];
      for (int k = 0; k < 3; ++k) {
        store(lane_x[k], ox[k]);
        store(lane_y[k], oy[k]);
        oinv_w[k] = select(swapped, o[k == 0 ? 0 : 3 - k]->inv_w, o[k]->inv_w);
        store(lane_bias[k], bias[k]);
      }
      store(lane_box[0], x0);
      store(lane_box[1], y0);
      store(lane_box[2], x1);
      store(lane_box[3], y1);
      // plane_keys_over_area and perspective_weights, four lanes at a time (a half without
      // survivors is skipped).
      constexpr double kMinArea = SnapShift::kMinArea;
      f4 key_over_area[3][2] = {}, persp[3][2] = {};
      for (int h = 0; h < 2; ++h) {
        if ((keep >> (4 * h) & 0xfu) == 0) continue;
        const d4 t_area2 = abs(area2[h]);
        store(lane_area2 + 4 * h, t_area2);
        const d4 dx0 = wide(odx[0], h), dy0 = wide(ody[0], h);
        const d4 ex1 = wide(ox[1] - ox[0], h) + (wide(odx[1], h) - dx0);
        const d4 ey1 = wide(oy[1] - oy[0], h) + (wide(ody[1], h) - dy0);
        const d4 ex2 = wide(ox[2] - ox[0], h) + (wide(odx[2], h) - dx0);
        const d4 ey2 = wide(oy[2] - oy[0], h) + (wide(ody[2], h) - dy0);
        const d4 area = ex1 * ey2 - ey1 * ex2;
        const d4 r = 1.0 / (area * t_area2);
        const d4 inv_area = t_area2 * r, inv_area2 = area * r;
        const d4 key0 = wide(okey[0], h);
        const d4 dkey1 = wide(okey[1], h) - key0, dkey2 = wide(okey[2], h) - key0;
        l4 well_shaped = abs(area) > kMinArea;
        d4 fitted[3], mu[3][3];  // mu[k][j]: SnapShift of vertex k
        for (int k = 0; k < 3; ++k) {
          const d4 key = wide(okey[k], h);
          const d4 sx = -wide(odx[k], h), sy = -wide(ody[k], h);
          const d4 mu1 = (sx * ey2 - sy * ex2) * inv_area, mu2 = (ex1 * sy - ey1 * sx) * inv_area;
          const d4 mu0 = -(mu1 + mu2);
          mu[k][0] = mu0;
          mu[k][1] = mu1;
          mu[k][2] = mu2;
          fitted[k] = key + (mu1 * dkey1 + mu2 * dkey2);
          well_shaped &= (abs(mu0) <= 0.25) & (abs(mu1) <= 0.25) & (abs(mu2) <= 0.25) &
                         ((fitted[k] > 0.0) == (key > 0.0));
        }
        exact |= (~mask_bits(well_shaped) & 0xfu) << (4 * h);  // kExactDepth: slivers
        // The plain keys' division only where a surviving lane needs it (slivers are rare).
        d4 inv_t_area2{};
        if (~mask_bits(well_shaped) & keep >> (4 * h) & 0xfu) inv_t_area2 = 1.0 / t_area2;
        for (int k = 0; k < 3; ++k)
          key_over_area[k][h] = __builtin_convertvector(
              select(well_shaped, fitted[k] * inv_area2, wide(okey[k], h) * inv_t_area2), f4);
        if (params.shade) {
          const d4 w0 = wide(oinv_w[0], h), w1 = wide(oinv_w[1], h), w2 = wide(oinv_w[2], h);
          const d4 scale = 1.0 / (max(max(w0, w1), w2) * t_area2);
          const d4 pd[3] = {w0 * scale, w1 * scale, w2 * scale};
          for (int k = 0; k < 3; ++k) persp[k][h] = __builtin_convertvector(pd[k], f4);
          if (params.exact_weights) {  // setup.cpp, perspective_weights; slivers: diag(persp)
            const i4 keep_exact = __builtin_convertvector(well_shaped, i4);
            for (int j = 0; j < 3; ++j)
              for (int k = 0; k < 3; ++k) {
                const f4 exact = __builtin_convertvector(pd[j] * ((j == k ? 1.0 : 0.0) + mu[k][j]), f4);
                const f4 snapped = j == k ? persp[j][h] : f4{};
                store(&lane_q[j][k][4 * h], f4((i4(exact) & keep_exact) | (i4(snapped) & ~keep_exact)));
              }
          }
        }
      }
      for (int k = 0; k < 3; ++k) {
        store(lane_key[k], __builtin_shufflevector(key_over_area[k][0], key_over_area[k][1],
                                                   0, 1, 2, 3, 4, 5, 6, 7));
        store(lane_persp[k], __builtin_shufflevector(persp[k][0], persp[k][1],
                                                     0, 1, 2, 3, 4, 5, 6, 7));
      }
    }
  }

  for (unsigned todo = keep | special; todo != 0; todo &= todo - 1) {
    const int j = __builtin_ctz(todo);
    if (special >> j & 1) {
      setup_face(params, f + j, out);
      continue;
    }
    TriangleSetup& t = out.records.emplace_back();  // written in place, every field
    for (int k = 0; k < 3; ++k) {
      t.x[k] = lane_x[k][j];
      t.y[k] = lane_y[k][j];
      t.key_over_area[k] = lane_key[k][j];
      t.bias[k] = uint8_t(lane_bias[k][j]);
    }
    t.flags = (exact >> j & 1) ? kExactDepth : 0;
    t.x0 = lane_box[0][j];
    t.y0 = lane_box[1][j];
    t.x1 = lane_box[2][j];
    t.y1 = lane_box[3][j];
    t.prim = uint32_t(f + j);
    t.draw = params.draw;
    if (params.shade) {
      TriangleShading& a = out.shading.emplace_back();
      const bool swapped = negative >> j & 1;
      const int32_t* vertex = face_index + 3 * j;
      for (int k = 0; k < 3; ++k) a.persp[k] = lane_persp[k][j];
      a.vertex[0] = vertex[0];
      a.vertex[1] = vertex[swapped ? 2 : 1];
      a.vertex[2] = vertex[swapped ? 1 : 2];
      a.clip_ref = kNoClip;
      a.swapped = swapped ? 1 : 0;
      a.back_facing = (front >> j & 1) ? 0 : 1;
      if (params.exact_weights) {
        ExactWeights& e = out.exact.emplace_back();
        for (int r = 0; r < 3; ++r)
          for (int k = 0; k < 3; ++k) e.q[r][k] = lane_q[r][k][j];
      }
    }
    emit(t.x0, t.y0, t.x1, t.y1, lane_area2[j], params.viewport, out);
  }
}

// Faces reach their vertices through indices, and the order of a mesh's vertices is its
// author's: in a large mesh each gather from the projected vertices may be a cache miss that no
// hardware prefetcher foresees. So the vertices of the faces this many places ahead are fetched
// early: that speeds up the setup of a large mesh whose vertices are out of order and changes
// nothing for a mesh that fits in cache (benchmarks/RESULTS.md, "Measurements behind the code").
constexpr std::size_t kPrefetchFaces = 64;

SR_INLINE void setup_range(const SetupParams& params, std::size_t begin, std::size_t end,
                           SetupChunk& out) {
  const std::size_t num_faces = params.mesh->faces.size();
  std::size_t f = begin;
  for (; f + kLanes <= end; f += kLanes) {
    if (f + kPrefetchFaces + kLanes <= num_faces) {
      const int32_t* ahead = &params.mesh->faces[f + kPrefetchFaces].x;
      for (int j = 0; j < 3 * kLanes; ++j) __builtin_prefetch(params.vertices + ahead[j]);
    }
    setup_eight(params, f, out);
  }
  for (; f < end; ++f) setup_face(params, f, out);
}

struct SetupRange {
  SR_INLINE static void run(const SetupParams& params, std::size_t begin, std::size_t end,
                            SetupChunk& out) {
    setup_range(params, begin, end, out);
  }
};
using SetupRangeFn = void (*)(const SetupParams&, std::size_t, std::size_t, SetupChunk&);

}  // namespace

void setup_faces(const SetupParams& params, std::size_t begin, std::size_t end, SetupChunk& out) {
  dispatch::IsaKernel<SetupRange, SetupRangeFn>::get(params.isa)(params, begin, end, out);
}

}  // namespace sr
