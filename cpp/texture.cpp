// Texture sampling (texture.hpp), scalar and compiled once, for the generic target: the AVX2 and
// generic shading kernels call this same code. The formulas are python/softrast/texture.py's.
#include "texture.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace sr {
namespace {

// uint8 decode tables: v / 255 and the IEC 61966-2-1 sRGB decode of v / 255, each rounded once
// from double.
struct Luts {
  float linear[256], srgb[256];
  Luts() {
    for (int i = 0; i < 256; ++i) {
      const double c = i / 255.0;
      linear[i] = float(c);
      srgb[i] = float(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
    }
  }
};
const Luts& luts() {
  static const Luts tables;
  return tables;
}

// The exact area-weighted box filter of one row of n values (stride `step` floats, 4 channels)
// down to m = max(1, n / 2): out[i] averages [i n / m, (i + 1) n / m).
void box_down(const float* src, int n, int src_step, float* dst, int m, int dst_step) {
  const double scale = double(n) / m;
  for (int i = 0; i < m; ++i) {
    const double a = i * scale, b = (i + 1) * scale;
    double acc[4] = {0, 0, 0, 0};
    for (int j = int(a); j < n && j < b; ++j) {
      const double w = std::min(b, double(j + 1)) - std::max(a, double(j));
      for (int c = 0; c < 4; ++c) acc[c] += w * src[std::size_t(j) * src_step + c];
    }
    for (int c = 0; c < 4; ++c) dst[std::size_t(i) * dst_step + c] = float(acc[c] / scale);
  }
}

// floor for |x| < 2^31 without a libm call (the generic x86-64 target has no SSE4.1 round).
inline float fast_floor(float x) {
  const float t = float(int(x));
  return t > x ? t - 1.0f : t;
}

// ceil for |x| < 2^31 (no libm call either).
inline float fast_ceil(float x) {
  const float t = float(int(x));
  return t < x ? t + 1.0f : t;
}

// log2(x) for x > 0 without a libm call: x = 2^e m, m in [sqrt(1/2), sqrt(2)), log2(m) by the
// atanh series (lighting.hpp's log2_pos, scalar; error < 1e-8). inf gives a large value (the
// callers clamp the level), denormals count as 2^-126.
inline float fast_log2(float x) {
  if (!(x < 3.0e38f)) return 128.0f;
  if (x < 1.17549435e-38f) x = 1.17549435e-38f;
  uint32_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  int e = int((bits >> 23) & 0xff) - 127;
  bits = (bits & 0x007fffffu) | 0x3f800000u;
  float m;
  std::memcpy(&m, &bits, sizeof m);
  if (m > 1.41421356f) {
    m *= 0.5f;
    ++e;
  }
  const float t = (m - 1.0f) / (m + 1.0f), t2 = t * t;
  const float series = t * (2.0f + t2 * (0.666666667f + t2 * (0.4f + t2 * (0.285714286f + t2 * 0.222222222f))));
  return float(e) + series * 1.44269504f;
}

inline int wrap_index(int i, int n, Wrap wrap) {
  if (unsigned(i) < unsigned(n)) return i;  // inside: the common case
  switch (wrap) {
    case Wrap::Repeat: {
      if (i < 0 && i >= -n) return i + n;  // reduced coordinates give i in [-1, n]
      if (i >= n && i < 2 * n) return i - n;
      const int m = i % n;
      return m < 0 ? m + n : m;
    }
    case Wrap::Clamp: return i < 0 ? 0 : n - 1;
    case Wrap::Mirror: {
      int m = i >= 0 && i < 2 * n ? i : i % (2 * n);
      if (m < 0) m += 2 * n;
      return m < n ? m : 2 * n - 1 - m;
    }
  }
  return 0;
}

// A coordinate reduced to one period (exactly: u - floor(u) is exact in float), so that huge
// uvs keep their fraction; clamp only bounds it (texel indices then stay small).
inline float reduce(float u, Wrap wrap) {
  switch (wrap) {
    case Wrap::Repeat: return u - (std::fabs(u) < 2e9f ? fast_floor(u) : std::floor(u));
    case Wrap::Mirror: {
      const float h = u * 0.5f;
      return u - 2.0f * (std::fabs(h) < 2e9f ? fast_floor(h) : std::floor(h));
    }
    case Wrap::Clamp: return u < -1.0f ? -1.0f : (u > 2.0f ? 2.0f : u);
  }
  return u;
}

struct Coords {
  float u, v;  // reduced
};

vec4 nearest(const Texture& t, int level, Coords c) {
  const int w = t.level_width(level), h = t.level_height(level);
  const float x = c.u * float(w);
  const float y = t.top_left ? c.v * float(h) : (1.0f - c.v) * float(h);
  const int j = wrap_index(int(fast_floor(x)), w, t.wrap_u);
  const int r = wrap_index(int(fast_floor(y)), h, t.wrap_v);
  return t.texel(level, j, r);
}

vec4 bilinear(const Texture& t, int level, Coords c) {
  const int w = t.level_width(level), h = t.level_height(level);
  const float x = c.u * float(w) - 0.5f;
  const float y = (t.top_left ? c.v * float(h) : (1.0f - c.v) * float(h)) - 0.5f;
  const float fx0 = fast_floor(x), fy0 = fast_floor(y);
  const float fx = x - fx0, fy = y - fy0;
  const int x0 = int(fx0), y0 = int(fy0);
  const int j0 = wrap_index(x0, w, t.wrap_u), j1 = wrap_index(x0 + 1, w, t.wrap_u);
  const int r0 = wrap_index(y0, h, t.wrap_v), r1 = wrap_index(y0 + 1, h, t.wrap_v);
  const vec4 t00 = t.texel(level, j0, r0), t01 = t.texel(level, j1, r0);
  const vec4 t10 = t.texel(level, j0, r1), t11 = t.texel(level, j1, r1);
  const vec4 top = t00 + (t01 - t00) * fx, bottom = t10 + (t11 - t10) * fx;
  return top + (bottom - top) * fy;
}

vec4 trilinear(const Texture& t, float lambda, Coords c) {
  const int last = t.has_mips() ? t.num_levels() - 1 : 0;
  lambda = lambda > 0.0f ? lambda : 0.0f;  // NaN -> 0
  lambda = lambda < float(last) ? lambda : float(last);
  const int l0 = int(lambda);
  const float f = lambda - float(l0);
  const vec4 a = bilinear(t, l0, c);
  if (f == 0.0f || l0 >= last) return a;
  const vec4 b = bilinear(t, l0 + 1, c);
  return a + (b - a) * f;
}

}  // namespace

int mip_level_count(int width, int height) {
  int levels = 1;
  while (width > 1 || height > 1) {
    width = std::max(1, width / 2);
    height = std::max(1, height / 2);
    ++levels;
  }
  return levels;
}

Texture::Texture(int width, int height, int channels, const uint8_t* texels, bool srgb)
    : width_(width), height_(height), channels_(channels), u8_(texels),
      lut_(srgb ? luts().srgb : luts().linear), alpha_lut_(luts().linear),
      num_levels_(mip_level_count(width, height)) {}

Texture::Texture(int width, int height, int channels, const float* texels)
    : width_(width), height_(height), channels_(channels), f32_(texels),
      num_levels_(mip_level_count(width, height)) {}

void Texture::build_mips() {
  std::call_once(mips_once_, [this] {
    std::vector<Level> levels;
    int w = width_, h = height_;
    std::vector<float> cur(std::size_t(w) * h * 4);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const vec4 v = texel(0, x, y);
        for (int c = 0; c < 4; ++c) cur[(std::size_t(y) * w + x) * 4 + c] = v[c];
      }
    while (w > 1 || h > 1) {
      const int mw = std::max(1, w / 2), mh = std::max(1, h / 2);
      std::vector<float> tmp(std::size_t(mw) * h * 4);  // columns first: each row, w -> mw
      for (int y = 0; y < h; ++y)
        box_down(cur.data() + std::size_t(y) * w * 4, w, 4, tmp.data() + std::size_t(y) * mw * 4, mw, 4);
      Level next{mw, mh, std::vector<float>(std::size_t(mw) * mh * 4)};
      for (int x = 0; x < mw; ++x)  // then each column, h -> mh
        box_down(tmp.data() + std::size_t(x) * 4, h, mw * 4, next.rgba.data() + std::size_t(x) * 4, mh, mw * 4);
      cur = next.rgba;
      w = mw;
      h = mh;
      levels.push_back(std::move(next));
    }
    mips_ = std::move(levels);
    mips_ready_ = true;
  });
}

vec4 sample_texture(const Texture& t, TextureFilter filter, float u, float v, float dudx,
                    float dvdx, float dudy, float dvdy) {
  const Coords c{reduce(u, t.wrap_u), reduce(v, t.wrap_v)};
  if (std::isnan(c.u) || std::isnan(c.v)) return vec4(0.0f);  // an infinite uv, repeated
  switch (filter) {
    case TextureFilter::Nearest: return nearest(t, 0, c);
    case TextureFilter::Bilinear: return bilinear(t, 0, c);
    default: break;
  }
  const float w = float(t.width()), h = float(t.height());
  const float ax = std::sqrt((dudx * w) * (dudx * w) + (dvdx * h) * (dvdx * h));
  const float ay = std::sqrt((dudy * w) * (dudy * w) + (dvdy * h) * (dvdy * h));
  if (filter == TextureFilter::Trilinear || !t.has_mips()) {
    const float rho = std::isnan(ax) || std::isnan(ay) ? 0.0f : (ax > ay ? ax : ay);
    return trilinear(t, rho > 0.0f ? fast_log2(rho) : 0.0f, c);
  }
  // Anisotropic (EXT_texture_filter_anisotropic): N probes along the footprint's major axis,
  // each trilinear at the level of the minor extent (or of Pmax / max_anisotropy).
  if (std::isnan(ax) || std::isnan(ay)) return trilinear(t, 0.0f, c);
  const bool x_major = !(ax < ay);
  const float pmax = x_major ? ax : ay, pmin = x_major ? ay : ax;
  if (!(pmax > 0.0f)) return trilinear(t, 0.0f, c);  // no footprint
  const int max_n = t.max_anisotropy;
  // ceil(Pmax / Pmin - 1/64): an isotropic footprint whose derivatives round a little apart
  // stays one probe (the 1/64 absorbs float rounding).
  const float ratio = pmax / pmin - 0.015625f;  // pmin = 0: inf
  int n = ratio < float(max_n) ? int(fast_ceil(ratio)) : max_n;
  n = n < 1 ? 1 : n;
  const float lambda = fast_log2(pmax / float(n));
  const float du = x_major ? dudx : dudy, dv = x_major ? dvdx : dvdy;
  if (!std::isfinite(du) || !std::isfinite(dv)) return trilinear(t, lambda, c);
  vec4 acc(0.0f);
  for (int i = 0; i < n; ++i) {
    const float s = (float(i) + 0.5f) / float(n) - 0.5f;
    const Coords ci{reduce(u + du * s, t.wrap_u), reduce(v + dv * s, t.wrap_v)};
    if (std::isnan(ci.u) || std::isnan(ci.v)) continue;
    acc += trilinear(t, lambda, ci);
  }
  return acc * (1.0f / float(n));
}

void sample_texture8(const Texture& t, TextureFilter filter, const float* u, const float* v,
                     const float* dudx, const float* dvdx, const float* dudy, const float* dvdy,
                     uint32_t mask, float (*out)[8]) {
  for (int i = 0; i < 8; ++i) {
    if (!(mask >> i & 1)) continue;
    const vec4 s = sample_texture(t, filter, u[i], v[i], dudx[i], dvdx[i], dudy[i], dvdy[i]);
    for (int c = 0; c < 4; ++c) out[c][i] = s[c];
  }
}

}  // namespace sr
