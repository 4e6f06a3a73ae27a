// Bindings: a render. Its options arrive as one dict read by name (kOptions below: each option's
// type and meaning, exported as _core.RENDER_OPTIONS for the stub), its draws as records
// (records.cpp); the GIL is released while the core renders, and each output's buffer becomes a
// NumPy array that owns it (no copy), or was the caller's own array (out=).
#include "bind.hpp"
#include "gil.hpp"
#include "records.hpp"

#include "../framebuffer.hpp"
#include "../lines.hpp"
#include "../renderer.hpp"
#include "../thread_pool.hpp"

#include <array>
#include <cstdint>

namespace sr {
namespace bind {

using namespace pybind11::literals;

namespace {

// A render's options: the one list of their names, Python types and meanings (render.py sends
// them checked by name; the core checks what Python cannot, and ranges, again).
enum OptionKey {
  k_view, k_proj, k_orthographic, k_near, k_far, k_outputs, k_cull, k_shading, k_shading_path,
  k_background, k_ambient, k_out, k_lights, k_ambient_light, k_frequency, k_srgb,
  k_texture_filter, k_normal_rotation, k_raster, k_msaa, k_ssaa, k_primitives, k_line_algorithm,
  k_lit_kernel, k_cull_double_sided, k_normal_kind, k_alpha_threshold, kNumOptions
};
struct OptionDoc {
  const char* key;
  const char* type;
  bool required;
  const char* doc;
};
constexpr OptionDoc kOptions[kNumOptions] = {
    {"view", "numpy.ndarray", true, "world -> view, (4, 4) float64, OpenGL axes"},
    {"proj", "numpy.ndarray", true, "view -> clip, (4, 4) float64"},
    {"orthographic", "bool", true, "an orthographic projection (depth keys are -depth)"},
    {"near", "float", true, "> 0, scene units along the viewing axis"},
    {"far", "float", true, "> near"},
    {"outputs", "list[str]", true, "names from OUTPUTS, at least one"},
    {"cull", "str", false, "CULL_MODES (default 'back')"},
    {"shading", "str", false,
     "SHADING_MODELS: 'auto' (default: each material's model, Lambert without one) or one "
     "model for every draw"},
    {"shading_path", "str", false, "SHADING_PATHS (default 'auto')"},
    {"background", "tuple[float, float, float]", false, "colour of uncovered pixels, [0, 1]"},
    {"ambient", "float", false,
     "[0, 1]: the headlight's ambient share, in a scene without lights (default 0.25)"},
    {"out", "dict[str, numpy.ndarray] | None", false, "arrays to render into in place"},
    {"lights", "list[Light]", false, "the scene's lights, world space (none: the headlight)"},
    {"ambient_light", "tuple[float, float, float] | None", false,
     "the scene's ambient light (None: 0, or the headlight's ambient)"},
    {"frequency", "str", false, "FREQUENCIES (default 'pixel')"},
    {"srgb", "bool", false, "the colour output sRGB-encoded (default True)"},
    {"texture_filter", "str | None", false, "TEXTURE_FILTERS for every texture, or None: each its own"},
    {"normal_rotation", "tuple[tuple[float, float, float], ...] | None", false,
     "rows of the world -> camera rotation for normal_space='camera', or None"},
    {"raster", "str", false, "RASTER_ALGORITHMS (default 'edge')"},
    {"msaa", "int", false, "1, 2, 4, 8 or 16 samples per pixel (default 1)"},
    {"ssaa", "int", false, "a k x k grid of samples per pixel, k in [1, 8] (default 1)"},
    {"primitives", "list[Primitive]", false, "lines and points drawn over the triangles"},
    {"line_algorithm", "str", false, "LINE_ALGORITHMS (default 'bresenham')"},
    {"lit_kernel", "bool", false,
     "tests and benchmarks: shade with the lit kernel even where a plain one serves (the same "
     "bits; default False)"},
    {"cull_double_sided", "bool", false,
     "cull the draws of double-sided materials too (default False: they are never culled)"},
    {"normal_kind", "str", false,
     "NORMAL_KINDS: the normal output's 'interpolated' vertex normal (default) or the 'shading' "
     "normal (normal and bump maps applied)"},
    {"alpha_threshold", "float | None", false,
     "[0, 1]: depth, ids, mask, normal and the surface outputs from the nearest blended "
     "fragment whose alpha reaches it, in front of the opaque surface; None (default): the "
     "nearest opaque surface's"},
};

// The options' keys, interned once (a lookup by a C string would build and hash a new Python
// string per key per render).
PyObject* const* option_keys() {
  // Made on first use with the GIL held and never freed (they live as long as the interpreter).
  static PyObject* const* const keys = [] {
    static PyObject* made[kNumOptions];
    for (int i = 0; i < kNumOptions; ++i) made[i] = PyUnicode_InternFromString(kOptions[i].key);
    return made;
  }();
  return keys;
}

// Which option `key` names (an interned key compares by identity), or -1.
int option_index(PyObject* key) {
  PyObject* const* keys = option_keys();
  for (int i = 0; i < kNumOptions; ++i)
    if (key == keys[i]) return i;
  for (int i = 0; i < kNumOptions; ++i)
    if (PyUnicode_Check(key) && PyUnicode_Compare(key, keys[i]) == 0) return i;
  return -1;
}

uint32_t parse_outputs(const std::vector<std::string>& names) {
  uint32_t bits = 0;
  for (const std::string& name : names) {
    int found = -1;
    for (int i = 0; i < kNumOutputs; ++i)
      if (name == kOutputLayouts[i].name) found = i;
    if (found < 0) {
      std::string known;
      for (const OutputLayout& l : kOutputLayouts) known += std::string(known.empty() ? "" : ", ") + l.name;
      throw py::value_error("outputs: unknown output '" + name + "'; choose from " + known);
    }
    bits |= kOutputLayouts[found].bit;
  }
  if (bits == 0) throw py::value_error("outputs must name at least one output");
  return bits;
}


std::vector<py::ssize_t> output_shape(const OutputLayout& layout, int width, int height) {
  std::vector<py::ssize_t> shape = {height, width};
  if (layout.channels > 1) shape.push_back(layout.channels);
  return shape;
}

// Wraps one framebuffer output as a NumPy array that owns it (via a capsule): no copy. When the
// array (and every view of it) is gone, its buffer goes back to the renderer's pool for the next
// render of that size (framebuffer.hpp, BufferPool), or is freed if the pool is full.
struct HandedOver {
  std::shared_ptr<BufferPool> pool;
  std::byte* data;
  std::size_t bytes;
};
py::array hand_over(Framebuffer& fb, int index, const std::shared_ptr<BufferPool>& pool) {
  const OutputLayout& layout = kOutputLayouts[index];
  const std::size_t bytes = std::size_t(fb.width) * std::size_t(fb.height) * layout.bytes_per_pixel();
  std::byte* data = fb.release(index);
  auto* held = new HandedOver{pool, data, bytes};
  py::capsule owner(held, [](void* p) {
    std::unique_ptr<HandedOver> h(static_cast<HandedOver*>(p));
    h->pool->give(h->data, h->bytes);
  });
  return py::array(output_dtype(layout), output_shape(layout, fb.width, fb.height), {}, data, owner);
}

// Checks a caller-supplied output array: exact dtype and shape, C-contiguous, writeable.
std::byte* external_buffer(const py::handle& obj, const OutputLayout& layout, int width, int height) {
  const std::string name = std::string("out['") + layout.name + "']";
  if (!py::isinstance<py::array>(obj)) throw py::type_error(name + " must be a numpy array");
  auto arr = py::reinterpret_borrow<py::array>(obj);
  const auto shape = output_shape(layout, width, height);
  const bool shape_ok = arr.ndim() == py::ssize_t(shape.size()) &&
                        std::equal(shape.begin(), shape.end(), arr.shape());
  // By value, not identity (an unpickled array's dtype is a distinct but equal object). The core
  // writes native-endian values in place, so a byte-swapped array ('>f4') is refused, not converted.
  if (!arr.dtype().equal(output_dtype(layout)) || !shape_ok)
    throw py::value_error(name + " must be a " + std::string(py::str(output_dtype(layout))) +
                          " array (native byte order) of shape " +
                          std::string(py::str(py::tuple(py::cast(shape)))) + ", got a " +
                          std::string(py::str(arr.dtype())) + " array of shape " +
                          std::string(py::str(arr.attr("shape"))));
  if (!(arr.flags() & py::array::c_style)) throw py::value_error(name + " must be C-contiguous");
  if (!arr.writeable()) throw py::value_error(name + " must be writeable");
  return static_cast<std::byte*>(arr.mutable_data());
}


vec3 vec3_from(const py::handle& h) {
  const auto v = h.cast<std::array<float, 3>>();
  return vec3(v[0], v[1], v[2]);
}

// One render: the draws (Draw records) and the options, each read by name once.
py::dict render(Renderer& self, const py::sequence& draws_in, const py::dict& spec) {
  std::vector<Draw> draws;
  draws.reserve(py::len(draws_in));
  for (std::size_t d = 0; d < py::len(draws_in); ++d) {
    const py::object item = draws_in[d];
    if (!py::isinstance<DrawRecord>(item))
      throw py::type_error("draws[" + std::to_string(d) + "] must be a Draw record");
    const DrawRecord& record = item.cast<const DrawRecord&>();
    if (!record.mesh) throw py::value_error("draws[" + std::to_string(d) + "] has no mesh");
    draws.push_back(record.draw());
  }
  // Every option once, by name; unknown names are refused, required ones checked after.
  PyObject* value[kNumOptions] = {};
  PyObject *key, *item;
  Py_ssize_t pos = 0;
  while (PyDict_Next(spec.ptr(), &pos, &key, &item)) {  // borrowed references
    const int i = option_index(key);
    if (i < 0)
      throw py::value_error("render options: unknown option '" + std::string(py::str(key)) + "'");
    value[i] = item;
  }
  for (int i = 0; i < kNumOptions; ++i)
    if (kOptions[i].required && !value[i])
      throw py::value_error(std::string("render options: '") + kOptions[i].key + "' is required");
  const auto get = [&](OptionKey k) { return py::handle(value[k]); };
  const auto given = [&](OptionKey k) { return value[k] != nullptr && value[k] != Py_None; };
  const auto name = [&](OptionKey k) { return get(k).cast<std::string>(); };
  CameraParams camera;
  camera.view = matrix_from_array(get(k_view), "view");
  camera.proj = matrix_from_array(get(k_proj), "proj");
  camera.orthographic = get(k_orthographic).cast<bool>();
  camera.near = get(k_near).cast<double>();
  camera.far = get(k_far).cast<double>();
  RenderOptions options;
  options.outputs = parse_outputs(get(k_outputs).cast<std::vector<std::string>>());
  if (given(k_cull)) options.cull = parse_name(name(k_cull), kCullNames, "cull");
  if (given(k_cull_double_sided)) options.cull_double_sided = get(k_cull_double_sided).cast<bool>();
  if (given(k_normal_kind))
    options.shading_normals = parse_name(name(k_normal_kind), kNormalKindNames, "normal_kind") == 1;
  if (given(k_shading)) options.shading = parse_name(name(k_shading), kShadingNames, "shading");
  if (given(k_shading_path))
    options.shading_path = parse_name(name(k_shading_path), kShadingPathNames, "shading_path");
  if (given(k_raster)) options.raster = parse_name(name(k_raster), kRasterNames, "raster");
  if (given(k_background)) {
    const auto background = get(k_background).cast<std::array<float, 3>>();
    for (int c = 0; c < 3; ++c) options.background[c] = background[c];  // range: Renderer::render
  }
  if (given(k_ambient)) options.ambient = get(k_ambient).cast<double>();
  if (given(k_lights))
    for (const py::handle light : get(k_lights)) {
      if (!py::isinstance<Light>(light)) throw py::type_error("lights: each must be a Light record");
      options.lights.push_back(light.cast<const Light&>());
    }
  if (given(k_ambient_light)) {
    options.has_ambient_light = true;
    options.ambient_light = vec3_from(get(k_ambient_light));
  }
  if (given(k_frequency)) options.frequency = parse_name(name(k_frequency), kFrequencyNames, "frequency");
  if (given(k_srgb)) options.srgb = get(k_srgb).cast<bool>();
  if (given(k_lit_kernel)) options.lit_kernel = get(k_lit_kernel).cast<bool>();
  if (given(k_texture_filter))
    options.texture_filter = uint8_t(parse_name(name(k_texture_filter), kFilterNames, "texture_filter"));
  // Anti-aliasing (1: off); counts are checked by Renderer::render.
  if (given(k_msaa)) options.msaa = get(k_msaa).cast<int>();
  if (given(k_ssaa)) options.ssaa = get(k_ssaa).cast<int>();
  if (given(k_alpha_threshold)) {
    const double t = get(k_alpha_threshold).cast<double>();
    if (!(t >= 0.0 && t <= 1.0))
      throw py::value_error("alpha_threshold must be None or in [0, 1], got " + py::repr(get(k_alpha_threshold)).cast<std::string>());
    options.surface_threshold = true;
    options.alpha_threshold = float(t);
  }
  // Lines and points (none by default), and how lines are stepped.
  std::vector<PrimitiveDraw> primitives;
  if (given(k_primitives))
    for (const py::handle p : get(k_primitives)) {
      if (!py::isinstance<PrimitiveRecord>(p))
        throw py::type_error("primitives: each must be a Primitive record");
      primitives.push_back(p.cast<const PrimitiveRecord&>().draw);
    }
  const LineAlgorithm line_algorithm =
      given(k_line_algorithm)
          ? LineAlgorithm(parse_name(name(k_line_algorithm), kLineAlgorithmNames, "line_algorithm"))
          : LineAlgorithm::Bresenham;
  if (given(k_normal_rotation)) {
    const auto r = get(k_normal_rotation).cast<std::array<std::array<float, 3>, 3>>();  // rows
    options.normal_camera = true;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) options.normal_rotation[j][i] = r[i][j];  // glm: [column][row]
  }
  // Mip chains, built once per texture, for the textures whose filter needs them.
  std::vector<Texture*> need_mips;
  for (const Draw& d : draws)
    for (const Texture* t : d.material.textures())
      if (t && !t->has_mips()) {
        const TextureFilter f = options.texture_filter == kNoFilterOverride
                                    ? t->filter : TextureFilter(options.texture_filter);
        if (f == TextureFilter::Trilinear || f == TextureFilter::Anisotropic)
          need_mips.push_back(const_cast<Texture*>(t));
      }

  // Caller-supplied arrays (out=) are written in place; `out` keeps them alive meanwhile.
  std::byte* external[kNumOutputs] = {};
  py::dict out_dict = given(k_out) ? py::dict(py::reinterpret_borrow<py::object>(get(k_out)))
                                   : py::dict();
  for (int i = 0; i < kNumOutputs; ++i) {
    const OutputLayout& layout = kOutputLayouts[i];
    if ((options.outputs & layout.bit) && out_dict.contains(layout.name))
      external[i] = external_buffer(out_dict[layout.name], layout, self.width(), self.height());
  }
  // Overlapping outputs would corrupt each other. Each array is C-contiguous with its exact
  // shape, so it spans exactly [data, data + bytes).
  const auto begin = [&](int i) { return reinterpret_cast<std::uintptr_t>(external[i]); };
  const auto end = [&](int i) {
    const OutputLayout& l = kOutputLayouts[i];
    return begin(i) + std::size_t(self.width()) * std::size_t(self.height()) * l.bytes_per_pixel();
  };
  for (int i = 0; i < kNumOutputs; ++i)
    for (int j = i + 1; j < kNumOutputs; ++j)
      if (external[i] && external[j] && begin(i) < end(j) && begin(j) < end(i))
        throw py::value_error(std::string("out['") + kOutputLayouts[i].name + "'] and out['" +
                              kOutputLayouts[j].name + "'] share memory");

  // Python threads may render concurrently. The GIL is released and taken back by hand, not by
  // py::gil_scoped_release: see take_gil_or_park. Renderer::render must not wait for the GIL
  // (it does not: pure C++), else fork(), which waits for renders, could deadlock.
  std::unique_ptr<Framebuffer> fb;
  PyThreadState* const saved = PyEval_SaveThread();
  try {
    for (Texture* t : need_mips) t->build_mips();
    fb = self.render(draws, camera, options, external, primitives, line_algorithm);
  } catch (...) {
    take_gil_or_park(saved);
    throw;
  }
  take_gil_or_park(saved);
  py::dict result;
  for (int i = 0; i < kNumOutputs; ++i) {
    const OutputLayout& layout = kOutputLayouts[i];
    if (!(options.outputs & layout.bit)) continue;
    result[layout.name] = external[i] ? out_dict[layout.name] : hand_over(*fb, i, self.buffer_pool());
  }
  return result;
}

}  // namespace

py::dtype output_dtype(const OutputLayout& layout) {
  switch (layout.dtype) {
    case DType::U8: return py::dtype::of<uint8_t>();
    case DType::Bool: return py::dtype::of<bool>();
    case DType::I32: return py::dtype::of<int32_t>();
    case DType::U32: return py::dtype::of<uint32_t>();
    case DType::F32: return py::dtype::of<float>();
  }
  throw std::logic_error("output_dtype: unknown dtype");
}

void bind_render(py::module_& m) {
  py::list options;
  for (const OptionDoc& o : kOptions) options.append(py::make_tuple(o.key, o.type, o.required, o.doc));
  m.attr("RENDER_OPTIONS") = options;

  // Testing only (tests/test_lifecycle.py), hence the underscores.
  m.def("_fail_thread_start", &fail_thread_start, "n"_a,
        "Testing only: the n-th worker thread started from now on (1 = the next) fails as if "
        "the system had refused it; 0 = off.");
  m.def("_parked_threads", [] { return g_parked_threads.load(); },
        "Testing only: threads parked for good because they finished a render while the "
        "interpreter finalized.");

  // ValueError for threads outside [0, MAX_THREADS] (std::invalid_argument), RuntimeError naming
  // `threads` when the system refuses a worker thread (std::runtime_error; none is left running).
  py::class_<Renderer>(m, "Renderer")
      .def(py::init<int, int, int, bool>(), "width"_a, "height"_a, "threads"_a = 0, "simd"_a = true,
           "A renderer of width x height pixels on `threads` threads (0: one per core); simd=False "
           "runs the generic kernels (the same bits).")
      .def_property_readonly("width", &Renderer::width)
      .def_property_readonly("height", &Renderer::height)
      .def_property_readonly("threads", &Renderer::threads)
      .def_property_readonly("isa", [](const Renderer& r) { return std::string(isa_name(r.isa())); })
      .def("render", &render, "draws"_a, "options"_a,
           "Renders the draws (Draw records) with the options (RENDER_OPTIONS, by name): a dict "
           "of the requested outputs' arrays (OUTPUT_TABLE gives dtypes and shapes).");
}

}  // namespace bind
}  // namespace sr
