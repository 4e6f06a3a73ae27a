// Bindings: lens distortion's per-pixel passes (python/softrast/distortion.py), hence the
// underscores, and the anti-aliasing patterns' sample positions.
#include "bind.hpp"

#include "../distortion.hpp"
#include "../multisample.hpp"

#include <algorithm>

namespace sr {
namespace bind {

using namespace pybind11::literals;

namespace {

template <typename T>
const T* checked(const py::array& a, const char* name, py::ssize_t rows, py::ssize_t cols) {
  if (!py::isinstance<py::array_t<T>>(a) || !(a.flags() & py::array::c_style))
    throw py::value_error(std::string(name) + ": wrong dtype or not C-contiguous");
  const py::ssize_t size = rows * (cols > 0 ? cols : 1);
  if (a.size() != size || (a.size() > 0 && a.shape(0) != rows))
    throw py::value_error(std::string(name) + ": wrong shape");
  return static_cast<const T*>(a.data());
}

DistortionRays distortion_rays(const py::array& valid, const py::array& nearest, const py::array& corner,
                               const py::array& directions, int64_t view_width, int64_t view_size,
                               const std::array<double, 4>& sample_to_normalized) {
  DistortionRays rays;
  rays.n = valid.size();
  rays.view_width = view_width;
  rays.view_size = view_size;
  if (view_width < 2 || view_size < 2 * view_width || view_size % view_width != 0)
    throw py::value_error("view size: at least 2x2");
  rays.valid = checked<bool>(valid, "valid", rays.n, 0) ? reinterpret_cast<const uint8_t*>(valid.data()) : nullptr;
  rays.nearest = checked<int64_t>(nearest, "nearest", rays.n, 0);
  rays.corner = checked<int64_t>(corner, "corner", rays.n, 0);
  rays.directions = checked<double>(directions, "directions", rays.n, 3);
  std::copy(sample_to_normalized.begin(), sample_to_normalized.end(), rays.sample_to_normalized);
  bool inside = true;  // every index a gather or the resolve reads is in the view
  for (int64_t p = 0; p < rays.n; ++p)
    inside &= !rays.valid[p] || (rays.nearest[p] >= 0 && rays.nearest[p] < view_size && rays.corner[p] >= 0 &&
                                 rays.corner[p] + view_width + 1 < view_size);
  if (!inside) throw py::value_error("nearest / corner: index outside the view");
  return rays;
}

py::dict distortion_resolve(const py::array& valid, const py::array& nearest, const py::array& corner,
                            const py::array& directions, int64_t view_width, int64_t view_size,
                            const std::array<double, 4>& sample_to_normalized, const py::array& triangle_id,
                            const py::array& instance_id, const py::list& instances,
                            const std::array<double, 9>& camera_to_world, const std::array<double, 3>& centre,
                            bool surface, int threads) {
  const DistortionRays rays = distortion_rays(valid, nearest, corner, directions, view_width, view_size,
                                              sample_to_normalized);
  const int32_t* tri = checked<int32_t>(triangle_id, "triangle_id", view_size / view_width, view_width);
  const int32_t* inst = checked<int32_t>(instance_id, "instance_id", view_size / view_width, view_width);
  std::vector<RayInstance> ray_instances;
  std::vector<std::shared_ptr<MeshData>> keep;
  for (const py::handle item : instances) {
    const auto pair = item.cast<py::tuple>();
    keep.push_back(pair[0].cast<std::shared_ptr<MeshData>>());
    const auto m = pair[1].cast<std::array<double, 16>>();  // row-major 4x4
    RayInstance r;
    r.mesh = keep.back().get();
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) r.model[j][i] = m[std::size_t(4 * i + j)];  // GLM: [column][row]
    ray_instances.push_back(r);
  }
  dmat3 rot;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) rot[j][i] = camera_to_world[std::size_t(3 * i + j)];
  const py::ssize_t n = rays.n;
  py::array_t<int64_t> sample(n);
  py::array_t<bool> covered(n);
  DistortionHits hits;
  hits.sample = sample.mutable_data();
  hits.covered = reinterpret_cast<uint8_t*>(covered.mutable_data());
  py::dict result;
  result["sample"] = sample;
  result["covered"] = covered;
  if (surface) {
    py::array_t<double> depth(n), ray_depth(n), position({n, py::ssize_t(3)}), bary({n, py::ssize_t(3)});
    hits.depth = depth.mutable_data();
    hits.ray_depth = ray_depth.mutable_data();
    hits.position = position.mutable_data();
    hits.barycentric = bary.mutable_data();
    result["depth"] = depth;
    result["ray_depth"] = ray_depth;
    result["position"] = position;
    result["barycentric"] = bary;
  }
  {
    py::gil_scoped_release release;
    resolve_distorted(rays, tri, inst, std::move(ray_instances), rot, dvec3(centre[0], centre[1], centre[2]),
                      hits, threads);
  }
  return result;
}

void distortion_bilinear(const py::array& valid, const py::array& nearest, const py::array& corner,
                         const py::array& directions, int64_t view_width, int64_t view_size,
                         const py::array& weights, const py::array& src, py::array& out) {
  const DistortionRays rays = distortion_rays(valid, nearest, corner, directions, view_width, view_size,
                                              {0.0, 0.0, 0.0, 0.0});
  const float* w = checked<float>(weights, "weights", 4, rays.n);
  if (src.ndim() < 2 || src.shape(0) * (src.ndim() == 3 ? src.shape(1) : 1) != view_size)
    throw py::value_error("src: the view's (h, w[, c]) output");
  const int channels = src.ndim() == 3 ? int(src.shape(2)) : 1;
  if (!(out.flags() & py::array::c_style) || !out.writeable() || out.size() != rays.n * channels ||
      out.dtype().not_equal(src.dtype()) || !(src.flags() & py::array::c_style))
    throw py::value_error("out: a writeable C-contiguous array of the source's dtype, n x channels");
  if (py::isinstance<py::array_t<uint8_t>>(src)) {
    const auto* s = static_cast<const uint8_t*>(src.data());
    auto* o = static_cast<uint8_t*>(out.mutable_data());
    py::gil_scoped_release release;
    bilinear_gather(rays, w, s, channels, o);
  } else if (py::isinstance<py::array_t<float>>(src)) {
    const auto* s = static_cast<const float*>(src.data());
    auto* o = static_cast<float*>(out.mutable_data());
    py::gil_scoped_release release;
    bilinear_gather(rays, w, s, channels, o);
  } else {
    throw py::value_error("src: uint8 or float32");
  }
}

}  // namespace

void bind_distortion(py::module_& m) {
  m.def("_sample_pattern",
        [](int msaa, int ssaa) {
          const SamplePattern p = ssaa > 1 ? ssaa_pattern(ssaa) : msaa_pattern(msaa);
          std::vector<std::pair<int32_t, int32_t>> xy;
          for (int i = 0; i < p.count; ++i) xy.emplace_back(p.x[i], p.y[i]);
          return xy;
        },
        "msaa"_a, "ssaa"_a,
        "The sample offsets of an anti-aliasing mode, from each pixel's top-left corner in fixed "
        "point (1 / 2**SUBPIXEL_BITS px), in sample order (multisample.hpp).");
  m.def("_distortion_resolve", &distortion_resolve, "valid"_a, "nearest"_a, "corner"_a, "directions"_a,
        "view_width"_a, "view_size"_a, "sample_to_normalized"_a, "triangle_id"_a, "instance_id"_a,
        "instances"_a, "camera_to_world"_a, "centre"_a, "surface"_a, "threads"_a,
        "Per output pixel: the view sample it takes and, with surface, its point on its own ray.");
  m.def("_distortion_bilinear", &distortion_bilinear, "valid"_a, "nearest"_a, "corner"_a, "directions"_a,
        "view_width"_a, "view_size"_a, "weights"_a, "src"_a, "out"_a,
        "out[p] = the bilinear interpolation of src at pixel p's ray (uint8 rounded half up).");

}

}  // namespace bind
}  // namespace sr
