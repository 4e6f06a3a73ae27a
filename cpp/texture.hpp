// Textures: texel storage, mip chains and filtered sampling (nearest, bilinear, trilinear,
// anisotropic) with repeat / clamp / mirror wrapping. python/softrast/texture.py states the
// contract (coordinates, decoding, the mip filter, level of detail); python/softrast/reference/texture.py
// is an independent NumPy implementation of it.
//
// Sampling is scalar and out of line (texture.cpp, compiled once for the generic x86-64 target):
// both instruction sets' shading kernels call the same code, so a textured pixel has the same
// bits under AVX2 and generic kernels, and Texture.sample() in Python returns what a render reads.
#pragma once

#include "math.hpp"

#include <cstdint>
#include <mutex>
#include <vector>

namespace sr {

enum class TextureFilter : uint8_t { Nearest, Bilinear, Trilinear, Anisotropic };
enum class Wrap : uint8_t { Repeat, Clamp, Mirror };
constexpr uint8_t kNoFilterOverride = 0xff;

class Texture {
 public:
  // Level 0 is viewed, not copied: uint8 texels (decoded through a table, sRGB or linear) or
  // float32 linear texels, `channels` per texel, rows of width * channels. The owner (bindings.cpp)
  // keeps the array alive while this exists.
  Texture(int width, int height, int channels, const uint8_t* texels, bool srgb);
  Texture(int width, int height, int channels, const float* texels);

  int width() const { return width_; }
  int height() const { return height_; }
  int channels() const { return channels_; }
  int num_levels() const { return num_levels_; }
  // Level l is max(1, size >> l) on each side (known before the levels are built).
  int level_width(int l) const { return width_ >> l > 0 ? width_ >> l : 1; }
  int level_height(int l) const { return height_ >> l > 0 ? height_ >> l : 1; }

  // Builds levels 1.. (once; thread-safe). Sampling with trilinear or anisotropic needs them.
  void build_mips();
  bool has_mips() const { return mips_ready_; }

  // Linear RGBA of texel (x, y) of level l (indices already wrapped). Inline: the samplers'
  // inner loop.
  __attribute__((always_inline)) vec4 texel(int level, int x, int y) const;

  TextureFilter filter = TextureFilter::Trilinear;
  Wrap wrap_u = Wrap::Repeat, wrap_v = Wrap::Repeat;
  bool top_left = false;      // uv origin: row 0 at v = 0 (else at v = 1, OpenGL / glTF-as-loaded)
  int max_anisotropy = 16;

 private:
  struct Level {
    int width, height;
    std::vector<float> rgba;  // linear, straight alpha
  };
  int width_, height_, channels_;
  const uint8_t* u8_ = nullptr;
  const float* f32_ = nullptr;
  const float* lut_ = nullptr;  // uint8 decode table (sRGB or linear)
  const float* alpha_lut_ = nullptr;  // uint8 alpha: always linear
  int num_levels_ = 1;
  std::vector<Level> mips_;
  std::once_flag mips_once_;
  bool mips_ready_ = false;
};

inline vec4 Texture::texel(int level, int x, int y) const {
  if (level > 0) {
    const Level& l = mips_[level - 1];
    const float* p = l.rgba.data() + (std::size_t(y) * l.width + x) * 4;
    return vec4(p[0], p[1], p[2], p[3]);
  }
  const std::size_t i = (std::size_t(y) * width_ + x) * channels_;
  float c[4];
  if (u8_) {
    const uint8_t* p = u8_ + i;
    for (int k = 0; k < channels_; ++k) c[k] = lut_[p[k]];
    if (channels_ == 2 || channels_ == 4) c[channels_ - 1] = alpha_lut_[p[channels_ - 1]];
  } else {
    for (int k = 0; k < channels_; ++k) c[k] = f32_[i + k];
  }
  switch (channels_) {
    case 1: return vec4(c[0], c[0], c[0], 1.0f);
    case 2: return vec4(c[0], c[0], c[0], c[1]);
    case 3: return vec4(c[0], c[1], c[2], 1.0f);
    default: return vec4(c[0], c[1], c[2], c[3]);
  }
}

// Levels of a full chain down to 1x1 for a width x height level 0.
int mip_level_count(int width, int height);

// One sample: uv and its screen derivatives (du/dx, dv/dx, du/dy, dv/dy), linear RGBA. NaN uv
// gives (0, 0, 0, 0). Trilinear and anisotropic need build_mips() first (else level 0 only).
vec4 sample_texture(const Texture& t, TextureFilter filter, float u, float v, float dudx,
                    float dvdx, float dudy, float dvdy);

// Eight samples, the lanes of `mask` (bit i: lane i); out[c][i] channel c of lane i (others
// untouched). The shading kernels' entry point: plain arrays, so no vector crosses the call.
void sample_texture8(const Texture& t, TextureFilter filter, const float* u, const float* v,
                     const float* dudx, const float* dvdx, const float* dudy, const float* dvdy,
                     uint32_t mask, float (*out)[8]);

}  // namespace sr
