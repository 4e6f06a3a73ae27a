// Bindings: rasterizing triangles given in clip space (cpp/clip_raster.hpp), for softrast.nv
// (python/softrast/nv/, nvdiffrast's rasterize), hence the underscore. The outputs are the
// caller's arrays, written in place without the GIL.
#include "bind.hpp"
#include "gil.hpp"

#include "../clip_raster.hpp"

namespace sr {
namespace bind {

using namespace pybind11::literals;

namespace {

template <typename T>
bool is_c_array(const py::array& a) {
  return py::isinstance<py::array_t<T>>(a) && (a.flags() & py::array::c_style);
}

void rasterize_clip_arrays(const py::array& pos, const py::array& tri, const py::array& ranges, int width,
                           int height, py::array& rast, const py::object& rast_db, int threads, bool simd) {
  if (!is_c_array<float>(pos) || pos.ndim() != 3 || pos.shape(2) != 4 || pos.shape(0) < 1)
    throw py::value_error("pos: float32, C-contiguous, (1 or images, num_vertices, 4)");
  if (!is_c_array<int32_t>(tri) || tri.ndim() != 2 || tri.shape(1) != 3)
    throw py::value_error("tri: int32, C-contiguous, (num_triangles, 3)");
  if (!is_c_array<int64_t>(ranges) || ranges.ndim() != 2 || ranges.shape(1) != 2)
    throw py::value_error("ranges: int64, C-contiguous, (images, 2)");
  ClipRasterInput in;
  in.pos = static_cast<const float*>(pos.data());
  in.pos_images = pos.shape(0);
  in.num_vertices = pos.shape(1);
  in.tri = static_cast<const int32_t*>(tri.data());
  in.num_triangles = tri.shape(0);
  in.ranges = static_cast<const int64_t*>(ranges.data());
  in.images = ranges.shape(0);
  in.width = width;
  in.height = height;
  const auto output = [&](py::array& a, const char* name) {
    if (!is_c_array<float>(a) || !a.writeable() || a.ndim() != 4 || a.shape(0) != in.images ||
        a.shape(1) != height || a.shape(2) != width || a.shape(3) != 4)
      throw py::value_error(std::string(name) + ": a writeable C-contiguous float32 array of shape "
                            "(images, height, width, 4)");
    return static_cast<float*>(a.mutable_data());
  };
  float* const r = output(rast, "rast");
  float* db = nullptr;
  py::array db_array;
  if (!rast_db.is_none()) {
    db_array = rast_db.cast<py::array>();
    db = output(db_array, "rast_db");
    const auto* lo = static_cast<const char*>(db_array.data());
    const auto* hi = lo + db_array.nbytes();
    const auto* r_lo = reinterpret_cast<const char*>(r);
    if (r_lo < hi && lo < r_lo + rast.nbytes()) throw py::value_error("rast and rast_db share memory");
  }
  const Isa isa = simd ? best_isa() : Isa::Generic;
  // As a render does (render.cpp): the GIL released and taken back by hand (take_gil_or_park).
  PyThreadState* const saved = PyEval_SaveThread();
  try {
    rasterize_clip(in, r, db, threads, isa);
  } catch (...) {
    take_gil_or_park(saved);
    throw;
  }
  take_gil_or_park(saved);
}

}  // namespace

void bind_clip_raster(py::module_& m) {
  m.def("_rasterize_clip", &rasterize_clip_arrays, "pos"_a, "tri"_a, "ranges"_a, "width"_a, "height"_a, "rast"_a,
        "rast_db"_a, "threads"_a = 0, "simd"_a = true,
        "nvdiffrast's rasterize (softrast.nv) with the core's clipping and raster: triangles given in clip "
        "space, image k drawing tri[first:first + count] for ranges[k] = (first, count) with pos[k] (or "
        "pos[0] for every image). Writes rast = (u, v, z/w, id + 1) and rast_db = (du/dX, du/dY, dv/dX, "
        "dv/dY) (or None) in place, row 0 at the bottom (cpp/clip_raster.hpp), without the GIL; threads: "
        "0 = one per core; simd=False: the generic kernels (the same bits).");
}

}  // namespace bind
}  // namespace sr
