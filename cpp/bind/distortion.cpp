// Bindings: lens distortion's per-pixel passes (python/softrast/distortion.py), hence the
// underscores, and the anti-aliasing patterns' sample positions.
#include "bind.hpp"
#include "records.hpp"

#include "../distortion.hpp"
#include "../multisample.hpp"
#include "../texture.hpp"

#include <algorithm>
#include <cmath>

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
                               int64_t view_width, int64_t view_size) {
  DistortionRays rays;
  rays.n = valid.size();
  rays.view_width = view_width;
  rays.view_size = view_size;
  if (view_width < 2 || view_size < 2 * view_width || view_size % view_width != 0)
    throw py::value_error("view size: at least 2x2");
  rays.valid = checked<bool>(valid, "valid", rays.n, 0) ? reinterpret_cast<const uint8_t*>(valid.data()) : nullptr;
  rays.nearest = checked<int64_t>(nearest, "nearest", rays.n, 0);
  rays.corner = checked<int64_t>(corner, "corner", rays.n, 0);
  bool inside = true;  // every index a gather or the cast reads is in the view
  for (int64_t p = 0; p < rays.n; ++p)
    inside &= !rays.valid[p] || (rays.nearest[p] >= 0 && rays.nearest[p] < view_size && rays.corner[p] >= 0 &&
                                 rays.corner[p] + view_width + 1 < view_size);
  if (!inside) throw py::value_error("nearest / corner: index outside the view");
  return rays;
}

RayGrid ray_grid(const py::array& pixel, const py::array& xy, const py::array& slot, const py::array& cell_start,
                 int64_t nx, int64_t ny, const std::array<double, 4>& frame) {
  RayGrid g;
  g.n = slot.size();
  g.count = pixel.size();
  if (nx < 1 || ny < 1 || nx > (int64_t(1) << 24) || ny > (int64_t(1) << 24))
    throw py::value_error("ray grid: 1 to 2**24 cells a side");
  g.nx = nx, g.ny = ny;
  g.pixel = checked<int64_t>(pixel, "pixel", g.count, 0);
  g.xy = checked<double>(xy, "xy", g.count, 2);
  g.slot = checked<int64_t>(slot, "slot", g.n, 0);
  g.cell_start = checked<int64_t>(cell_start, "cell_start", nx * ny + 1, 0);
  g.x0 = frame[0], g.y0 = frame[1], g.inv_cell_x = frame[2], g.inv_cell_y = frame[3];
  if (!(std::isfinite(g.x0) && std::isfinite(g.y0) && g.inv_cell_x > 0.0 && g.inv_cell_y > 0.0 &&
        std::isfinite(g.inv_cell_x) && std::isfinite(g.inv_cell_y)))
    throw py::value_error("ray grid: a finite origin and positive cell sizes");
  bool ok = g.cell_start[0] == 0 && g.cell_start[nx * ny] == g.count;
  for (int64_t c = 0; ok && c < nx * ny; ++c) ok = g.cell_start[c] <= g.cell_start[c + 1];
  for (int64_t s = 0; ok && s < g.count; ++s)
    ok = g.pixel[s] >= 0 && g.pixel[s] < g.n && g.slot[g.pixel[s]] == s && std::isfinite(g.xy[2 * s]) &&
         std::isfinite(g.xy[2 * s + 1]);
  int64_t with_ray = 0;
  for (int64_t p = 0; ok && p < g.n; ++p) {
    ok = g.slot[p] >= -1 && g.slot[p] < g.count;
    with_ray += g.slot[p] >= 0;
  }
  if (!ok || with_ray != g.count)
    throw py::value_error("ray grid: pixel / slot / cell_start do not describe one another");
  return g;
}

// One camera's rays at one image size (python/softrast/distortion.py's _Rays), checked once: the
// arrays are kept (and must not be written afterwards: Python marks them read-only).
struct LensRays {
  std::vector<py::array> keep;
  DistortionRays rays;
  RayGrid grid;
};

std::shared_ptr<LensRays> make_lens_rays(const py::array& valid, const py::array& nearest, const py::array& corner,
                                         int64_t view_width, int64_t view_size, const py::array& pixel,
                                         const py::array& xy, const py::array& slot, const py::array& cell_start,
                                         int64_t nx, int64_t ny, const std::array<double, 4>& frame) {
  auto r = std::make_shared<LensRays>();
  r->keep = {valid, nearest, corner, pixel, xy, slot, cell_start};
  for (const py::array& a : r->keep)
    if (a.writeable()) throw py::value_error("lens rays: the arrays must be read-only");
  r->rays = distortion_rays(valid, nearest, corner, view_width, view_size);
  r->grid = ray_grid(pixel, xy, slot, cell_start, nx, ny, frame);
  if (r->rays.n != r->grid.n) throw py::value_error("lens rays: one entry per output pixel");
  for (int64_t p = 0; p < r->grid.n; ++p)
    if ((r->grid.slot[p] >= 0) != bool(r->rays.valid[p])) throw py::value_error("lens rays: valid must be slot >= 0");
  return r;
}

// Each output's buffer (flat, final dtype) for the names asked for.
template <typename T>
T* add_output(py::dict& result, const char* name, py::ssize_t n, py::ssize_t channels) {
  py::array_t<T> a = channels > 1 ? py::array_t<T>({n, channels}) : py::array_t<T>(n);
  result[name] = a;
  return a.mutable_data();
}

py::dict distortion_cast(const LensRays& lens, const py::list& draw_records, const std::array<double, 9>& camera_to_world,
                         const std::array<double, 3>& centre, double near, double far, const std::string& cull,
                         bool cull_double_sided, const std::vector<std::string>& outputs, const py::object& view,
                         int threads) {
  const RayGrid& grid = lens.grid;
  if (!(near > 0.0 && far > near && std::isfinite(far)))
    throw py::value_error("near, far: 0 < near < far, finite");
  const Cull cull_mode = parse_name(cull, kCullNames, "cull");
  std::vector<Draw> keep;  // the records' draws (their meshes alive for the call)
  keep.reserve(draw_records.size());
  std::vector<CastDraw> draws;
  for (const py::handle item : draw_records) {
    keep.push_back(item.cast<const DrawRecord&>().draw());
    const Draw& d = keep.back();
    if (!d.mesh) throw py::value_error("draws: a Draw without a mesh");
    CastDraw c;
    c.mesh = d.mesh.get();
    c.model = d.model;
    c.cull = d.never_culled && !cull_double_sided ? Cull::None : cull_mode;
    AlphaTest test;
    c.alpha = alpha_kind(d, kNoFilterOverride, test);
    draws.push_back(c);
  }
  CastCamera camera;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) camera.camera_to_world[j][i] = camera_to_world[std::size_t(3 * i + j)];
  camera.centre = dvec3(centre[0], centre[1], centre[2]);
  camera.near = near, camera.far = far;
  // The ideal view's ids, if rendered: (triangle_id, instance_id).
  CastView cast_view;
  if (!view.is_none()) {
    const auto t = view.cast<py::tuple>();
    if (t.size() != 2) throw py::value_error("view: (triangle_id, instance_id)");
    const DistortionRays& rays = lens.rays;
    const py::ssize_t rows = rays.view_size / rays.view_width;
    cast_view.rays = &rays;
    cast_view.triangle_id = checked<int32_t>(t[0].cast<py::array>(), "triangle_id", rows, rays.view_width);
    cast_view.instance = checked<int32_t>(t[1].cast<py::array>(), "instance_id", rows, rays.view_width);
  }
  const py::ssize_t n = grid.n;
  py::dict result;
  CastOutputs out;
  for (const std::string& name : outputs) {
    if (name == "triangle_id") out.triangle_id = add_output<int32_t>(result, "triangle_id", n, 1);
    else if (name == "instance_id") out.instance = add_output<int32_t>(result, "instance_id", n, 1);
    else if (name == "mask") out.mask = reinterpret_cast<uint8_t*>(add_output<bool>(result, "mask", n, 1));
    else if (name == "depth") out.depth = add_output<float>(result, "depth", n, 1);
    else if (name == "ray_depth") out.ray_depth = add_output<float>(result, "ray_depth", n, 1);
    else if (name == "position") out.position = add_output<float>(result, "position", n, 3);
    else if (name == "barycentric") out.barycentric = add_output<float>(result, "barycentric", n, 3);
    else if (name == "uv") out.uv = add_output<float>(result, "uv", n, 2);
    else if (name == "normal") out.normal = add_output<float>(result, "normal", n, 3);
    else if (name == "coverage") out.coverage = add_output<uint32_t>(result, "coverage", n, 1);
    else if (name == "alpha") out.alpha = add_output<float>(result, "alpha", n, 1);
    else if (name == "sample") {
      if (!cast_view.rays) throw py::value_error("outputs: sample needs the view");
      out.sample = add_output<int64_t>(result, "sample", n, 1);
    } else {
      throw py::value_error("outputs: no cast output named '" + name + "'");
    }
  }
  {
    py::gil_scoped_release release;
    cast_distorted(grid, draws, camera, cast_view, out, threads);
  }
  return result;
}

void distortion_bilinear(const LensRays& lens, const py::array& weights, const py::array& src, py::array& out) {
  const DistortionRays& rays = lens.rays;
  const float* w = checked<float>(weights, "weights", 4, rays.n);
  if (src.ndim() < 2 || src.shape(0) * (src.ndim() == 3 ? src.shape(1) : 1) != rays.view_size)
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
  py::class_<LensRays, std::shared_ptr<LensRays>>(
      m, "_LensRays", "One distorted camera's rays at one image size, checked once (distortion.py's _Rays).")
      .def(py::init(&make_lens_rays), "valid"_a, "nearest"_a, "corner"_a, "view_width"_a, "view_size"_a,
           "pixel"_a, "xy"_a, "slot"_a, "cell_start"_a, "nx"_a, "ny"_a, "frame"_a);
  m.def("_distortion_cast", &distortion_cast, "rays"_a, "draws"_a, "camera_to_world"_a, "centre"_a, "near"_a, "far"_a, "cull"_a,
        "cull_double_sided"_a, "outputs"_a, "view"_a, "threads"_a,
        "Per output pixel, the nearest hit of its own ray among every triangle of the draws (float64): "
        "the named outputs, flat.");
  m.def("_distortion_bilinear", &distortion_bilinear, "rays"_a, "weights"_a, "src"_a, "out"_a,
        "out[p] = the bilinear interpolation of src at pixel p's ray (uint8 rounded half up).");

}

}  // namespace bind
}  // namespace sr
