// Exact shadows (Light::shadow == ShadowMethod::Exact): whether a shaded point sees a light,
// decided by a ray from the point to the light against every occluding triangle, in double.
//
// The rule (python/softrast/light.py states it for users):
//   - the ray leaves the shaded point p toward the light: along -direction for a directional
//     light (any distance), toward the position of a point or spot light (only blockers between
//     p and the light count: 0 < t < 1 with d = light - p);
//   - a triangle blocks where the ray meets it (Moller-Trumbore in double, edges included);
//   - a triangle whose plane passes within eps of p never blocks it, eps = 2^-19 times the
//     largest coordinate magnitude of its corners and of p: p is a float32 point of the surface
//     it lies on (its interpolation error is a few float32 ulps of that surface's coordinates),
//     and a surface through the shaded point does not shadow it. This replaces a shadow bias: it
//     is not a distance along the ray, is the same for every scene, and gives no acne at any
//     angle (a floor under an 89.9 degree light is lit everywhere);
//   - the occluders are every triangle of every draw that is drawn opaque or masked (masked by
//     geometry: the alpha test is not applied to shadow rays), both faces, in the view or not;
//     blended and invisible draws cast none.
// Shadow maps (ShadowMethod::Map, python/softrast/shadow_maps.py renders them): the light's
// depth (along its view axis, softrast's `depth` output, 0 where nothing was hit) seen from one
// camera (directional: orthographic, fitted to the occluders; spot: perspective over the cone;
// point, or a spot wider than 150 degrees: six faces of a cube). A point p is looked up in the
// first face whose image holds it; its visibility is percentage-closer filtering as pyrender's
// mesh.frag does it: the mean of 3 x 3 bilinear interpolations, one texel apart, of the 0/1
// comparisons "the map's depth >= depth(p) - bias" at the four nearest texel centres (texels
// outside the map, or where nothing was hit, pass). bias = shadow_bias + 2 texels' width at p
// times tan(angle between the normal and the light), the tangent at most 10 (a slope-scaled
// bias). A point outside every face, or beyond a face's far plane, is lit.
//
// A shadowed light's diffuse and specular terms are multiplied by the visibility (0 or 1 exact,
// in [0, 1] from a map), in
// every lit model, at the point where the render's frequency evaluates the light (each pixel,
// each vertex, each face's centre); ambient and emissive light are not shadowed.
//
// The occluders sit in a bounding volume hierarchy (binned surface-area heuristic, at most four
// triangles a leaf) built once per render that has a shadowed light; a ray stops at its first
// blocker. Scalar and compiled once for the generic target: both instruction sets' kernels get
// the same decisions.
#pragma once

#include "materials.hpp"
#include "math.hpp"
#include "simd.hpp"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace sr {

struct Draw;
struct MeshData;

// One camera's depth map of a shadow-mapped light (rows from the top, as softrast's images).
struct ShadowMapFace {
  dmat4 view;  // world -> the light camera's view (OpenGL axes: looking down -z)
  dmat4 proj;  // view -> clip
  dmat4 view_proj;  // proj * view
  bool orthographic = false;
  int size = 0;  // size x size texels
  std::vector<float> depth;
  // For the eight-lane lookup (finish_face): the view's rotation rows, the light camera's
  // position (world), the projection's rows, and a texel's width over the view depth
  // (orthographic: the width itself).
  float rot[3][3];
  vec3 eye;
  float proj_rows[4][4];
  float texel_scale;
};
// Sets a face's view_proj and the lookup's float copies from its view, proj and size.
void finish_face(ShadowMapFace& f);

struct ShadowMap {
  std::vector<ShadowMapFace> faces;
  double bias = 0.0;  // shadow_bias, scene units
};


class ShadowScene {
 public:
  // The occluders: every triangle of each draw d with casts[d], posed in double by its model
  // matrix. Triangles of zero area (or not finite) are left out: no ray meets them. Kept as it
  // is when the casting draws are the same meshes under the same matrices as last time (a
  // dataset's views of one scene build it once); it holds those meshes until the next build.
  void build(const std::vector<Draw>& draws, const std::vector<uint8_t>& casts);
  // After build: a grid across each exactly shadowed directional light's direction (below), kept
  // while the occluders and the direction stay.
  void prepare(const std::vector<Light>& lights);
  // Whether an occluder blocks the ray from p toward `light` (the rule above).
  bool blocked(const Light& light, const dvec3& p) const;
  std::size_t size() const { return tris_.size(); }
  void clear() { tris_.clear(); nodes_.clear(); built_from_.clear(); grids_.clear(); }

 private:
  // Corners a, a + e1, a + e2; n = e1 x e2, nn = n . n, scale = the corners' largest coordinate
  // magnitude (the on-surface rule's).
  struct Tri { dvec3 a, e1, e2, n; double nn, scale; };
  // A leaf holds triangles [index, index + count); an inner node (count 0) has its children at
  // this + 1 and at `index`.
  struct Node { double bound[2][3]; uint32_t index, count; };  // bound[0] low, bound[1] high corner
  bool hits(const Tri& tri, const dvec3& o, const dvec3& d, double t_max) const;
  // A directional light's rays are parallel: a triangle can block one only where the ray's
  // point, projected along the light onto a plane across it, lies in the triangle's projection.
  // The grid lists, per cell of that plane, the triangles whose projected bounding box (padded
  // past rounding) meets the cell; a ray tests its cell's list, the same triangles' test as the
  // hierarchy's (so the same decisions: any listed triangle that blocks, none missed). A cell of
  // more than kGridCellMax triangles (a scene much wider than its detail) is left to the
  // hierarchy.
  struct DirectionGrid {
    vec3 direction;  // the light's, as given (the key)
    dvec3 u, v;      // the plane's axes (unit, across the direction)
    double s0 = 0.0, t0 = 0.0, inv_cell = 0.0;
    int nx = 0, ny = 0;
    std::vector<uint32_t> start;  // cell c's triangles: items[start[c], start[c + 1])
    std::vector<uint32_t> items;  // each cell's nearest the light first (by `reach`)
    // Per item, how far toward the light its triangle reaches (its corners' largest w . x,
    // padded): a ray from a point beyond it (w . o greater) cannot meet it, nor the rest.
    std::vector<double> reach;
    dvec3 w;  // toward the light (unit)
    std::vector<uint8_t> crowded;  // per cell: left to the hierarchy
  };
  void build_grid(DirectionGrid& grid) const;
  // The ray from o along d against cell c's list (not crowded).
  bool blocked_in_grid(const DirectionGrid& grid, std::size_t c, const dvec3& o, const dvec3& d) const;
  std::vector<DirectionGrid> grids_;
  std::vector<Node> nodes_;
  std::vector<Tri> tris_;
  std::vector<std::pair<std::shared_ptr<const MeshData>, dmat4>> built_from_;  // (mesh, model)
};

// The 4 x 4 filtered taps of map_lanes at a lookup near the map's border (texels outside pass).
float map_filtered(const ShadowMapFace& f, float sx, float sy, float compare);

namespace shadow_lanes {

// Comparisons of eight lanes as two halves of four: GCC lowers a comparison of 256-bit vectors
// to one scalar compare per lane on a target without AVX (the generic kernels'), but a 128-bit one to
// one SSE2 instruction.
using simd::f4;
using simd::f8;
using simd::i4;
using simd::i8;
SR_INLINE f4 lo4(f8 v) { return __builtin_shufflevector(v, v, 0, 1, 2, 3); }
SR_INLINE f4 hi4(f8 v) { return __builtin_shufflevector(v, v, 4, 5, 6, 7); }
SR_INLINE i4 lo4(i8 v) { return __builtin_shufflevector(v, v, 0, 1, 2, 3); }
SR_INLINE i4 hi4(i8 v) { return __builtin_shufflevector(v, v, 4, 5, 6, 7); }
SR_INLINE i8 join(i4 lo, i4 hi) { return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7); }
SR_INLINE i8 gt(f8 a, f8 b) { return join(lo4(a) > lo4(b), hi4(a) > hi4(b)); }
SR_INLINE i8 ge(f8 a, f8 b) { return join(lo4(a) >= lo4(b), hi4(a) >= hi4(b)); }
SR_INLINE i8 lt(f8 a, f8 b) { return join(lo4(a) < lo4(b), hi4(a) < hi4(b)); }
SR_INLINE i8 le(f8 a, f8 b) { return join(lo4(a) <= lo4(b), hi4(a) <= hi4(b)); }
SR_INLINE i8 ge(i8 a, i8 b) { return join(lo4(a) >= lo4(b), hi4(a) >= hi4(b)); }
SR_INLINE i8 lt(i8 a, i8 b) { return join(lo4(a) < lo4(b), hi4(a) < hi4(b)); }
SR_INLINE i8 eq(f8 a, f8 b) { return join(lo4(a) == lo4(b), hi4(a) == hi4(b)); }
SR_INLINE i8 ne(i8 a, i8 b) { return join(lo4(a) != lo4(b), hi4(a) != hi4(b)); }
// A select as bit operations (a vector ?: of floats becomes a branch per lane there too).
SR_INLINE f8 select(i8 m, f8 a, f8 b) { return f8((i8(a) & m) | (i8(b) & ~m)); }

}  // namespace shadow_lanes

// One face of map_lanes: writes out[i] for the lanes in `lanes` whose point the face's image
// holds (those beyond its far plane are left lit), and returns those lanes.
SR_INLINE uint32_t map_face_lanes(const ShadowMapFace& f, double bias, const Light& light,
                                  const simd::f8 (&p)[3], const simd::f8 (&n)[3], uint32_t lanes,
                                  float* out) {
  using namespace simd;
  using namespace shadow_lanes;
  // The point in the light camera's view, from its eye (small numbers, float), then clip space.
  const f8 r[3] = {p[0] - f.eye.x, p[1] - f.eye.y, p[2] - f.eye.z};
  f8 v[3];
  for (int k = 0; k < 3; ++k) v[k] = f.rot[k][0] * r[0] + f.rot[k][1] * r[1] + f.rot[k][2] * r[2];
  f8 c[4];
  for (int k = 0; k < 4; ++k)
    c[k] = f.proj_rows[k][0] * v[0] + f.proj_rows[k][1] * v[1] + f.proj_rows[k][2] * v[2] + f.proj_rows[k][3];
  const f8 zero = splat(0.0f);
  const f8 depth = -v[2];
  const f8 inv_w = f.orthographic ? splat(1.0f) : 1.0f / c[3];
  const float half = 0.5f * float(f.size);
  const f8 sx = (c[0] * inv_w + 1.0f) * half - 0.5f;
  const f8 sy = (1.0f - c[1] * inv_w) * half - 0.5f;
  // The slope-scaled bias: a texel's width at p times tan(normal, light), at most 10 (tan =
  // sqrt(|n|^2 |l|^2 - (n.l)^2) / |n.l|; 10 where cos < 0.0995).
  const f8 texel = f.orthographic ? splat(f.texel_scale) : depth * f.texel_scale;
  f8 l[3];
  for (int k = 0; k < 3; ++k)
    l[k] = light.kind == LightKind::Directional ? splat(-light.direction[k])
                                                : light.position[k] - p[k];
  const f8 n2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
  const f8 dot = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
  const f8 nl = f8(i8(dot) & 0x7fffffff);  // |dot|
  const f8 nl2 = n2 * (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
  const f8 rest = nl2 - nl * nl;
  const f8 tangent = simd::sqrt(f8(i8(rest) & gt(rest, zero))) / nl;
  const i8 steep = gt(nl, zero) & ge(nl * nl, splat(0.0995f * 0.0995f) * nl2);
  const f8 slope = f8(i8(select(steep, tangent, splat(10.0f))) & gt(n2, zero));
  const f8 compare = depth - (float(bias) + 2.0f * texel * slope);
  // The taps' texels, in lanes: the 4 x 4 block from (i0, j0), its fractions (fx, fy). (Lanes
  // outside the image, or not finite, are clamped first: only lanes inside are read, and the
  // conversion to integers must not overflow.)
  const f8 low = splat(-2.0f), high = splat(float(f.size) + 2.0f);
  const f8 cx = select(le(select(ge(sx, low), sx, low), high), select(ge(sx, low), sx, low), high);
  const f8 cy = select(le(select(ge(sy, low), sy, low), high), select(ge(sy, low), sy, low), high);
  const i8 xt = __builtin_convertvector(cx, i8), yt = __builtin_convertvector(cy, i8);  // (trunc)
  const i8 xf = xt + lt(cx, to_float(xt)), yf = yt + lt(cy, to_float(yt));  // floor (true is -1)
  const f8 fx = cx - to_float(xf), fy = cy - to_float(yf);
  const i8 i0 = xf - 1, j0 = yf - 1;
  const i8 izero = splat(0), last = splat(f.size - 3);
  const i8 inside_block = ge(i0, izero) & ge(j0, izero) & lt(i0, last) & lt(j0, last);
  // In the face's image; beyond its far plane, lit (not written).
  const f8 w = c[3];
  const i8 held = gt(w, zero) & le(c[0], w) & le(-c[0], w) & le(c[1], w) & le(-c[1], w);
  alignas(32) int32_t in_image[8], near[8], block[8], first[8];
  alignas(32) float fxs[8], fys[8], limit[8];
  store(in_image, held);
  store(near, le(c[2], w));
  store(block, inside_block);
  store(first, j0 * f.size + i0);
  store(fxs, fx);
  store(fys, fy);
  store(limit, compare);
  uint32_t inside = 0;
  for (int i = 0; i < 8; ++i) {
    if (!(lanes >> i & 1u) || !in_image[i]) continue;
    inside |= 1u << i;
    if (!near[i]) continue;
    if (!block[i]) {  // (at the map's border: texels outside pass)
      out[i] = map_filtered(f, sx[i], sy[i], compare[i]);
      continue;
    }
    // A row of four texels as one vector: its passing texels' weights, times the row's.
    using simd::f4;
    using simd::i4;
    const float* row = f.depth.data() + first[i];
    const f4 weights = {1.0f - fxs[i], 1.0f, 1.0f, fxs[i]};
    const float wy[4] = {1.0f - fys[i], 1.0f, 1.0f, fys[i]};
    const f4 cut = simd::broadcast<f4>(limit[i]);
    f4 acc = {};
    for (int b = 0; b < 4; ++b, row += f.size) {
      const f4 d = simd::load<f4>(row);
      const i4 pass = (d <= f4{}) | (d >= cut);
      acc += wy[b] * f4(pass & i4(weights));
    }
    out[i] = ((acc[0] + acc[1]) + (acc[2] + acc[3])) * (1.0f / 9.0f);
  }
  return inside;
}

// A shadow-mapped light's visibility in [0, 1] at eight points p with normals n (zero: no slope
// term), in float: out[i] for the lanes in `lanes`, from the first face whose image holds the
// point (the others are left as they are: lit). Inlined into the lighting kernels (lighting.hpp)
// for their instruction set and into shadow_lights: the same operations, the same bits.
SR_INLINE void map_lanes(const ShadowMap& map, const Light& light, const simd::f8 (&p)[3],
                         const simd::f8 (&n)[3], uint32_t lanes, float* out) {
  for (const ShadowMapFace& f : map.faces) {
    if (!lanes) return;
    lanes &= ~map_face_lanes(f, map.bias, light, p, n, lanes, out);
  }
}

// The visibility (1 or 0) of each light at the points (x[i], y[i], z[i]) of the lanes set in
// `mask` (bit i: lane i), at [8 k + i] for light k, in a buffer of the calling thread (valid
// until its next call). 1 for lights without shadows, in the other lanes, at points that are not
// finite, and, given normals (nx, ny, nz; else null), where the normal faces away from the light
// (n . (to the light) < -2^-20 |n| |to the light|: such a lane adds nothing from that light in
// the models that pass `facing`). A shadow-mapped light's visibility is its filtered fraction
// (map_lanes) in [0, 1]. Arrays cross the call (callers are compiled for AVX2 or not).
const float* shadow_lights(const ShadowScene& scene, const Light* lights, int num_lights,
                           const float* x, const float* y, const float* z, const float* nx,
                           const float* ny, const float* nz, bool facing, uint32_t mask);

}  // namespace sr
