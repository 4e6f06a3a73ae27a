// Python bindings (the only file that includes pybind11): argument checks, GIL release, and
// zero-copy hand-over of framebuffers to NumPy and of immutable mesh arrays to the core.
#include "distortion.hpp"
#include "framebuffer.hpp"
#include "pipeline.hpp"
#include "multisample.hpp"
#include "renderer.hpp"
#include "texture.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cxxabi.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <string>

namespace py = pybind11;
using namespace pybind11::literals;

namespace sr {
namespace {

static_assert(sizeof(vec3) == 3 * sizeof(float) && sizeof(ivec3) == 3 * sizeof(int32_t) &&
              sizeof(vec4) == 4 * sizeof(float) && sizeof(vec2) == 2 * sizeof(float),
              "GLM vectors must be tightly packed to view NumPy rows");

// Owns what a MeshData built from Python views: bytes objects under NumPy arrays (viewed in
// place) and copies of the arrays that could not be viewed.
struct PyMeshOwner {
  MeshVectors copies;
  std::vector<PyObject*> viewed;  // strong references
};

bool interpreter_finalizing() {
#if PY_VERSION_HEX >= 0x030D0000
  return Py_IsFinalizing();
#else
  return _Py_IsFinalizing();
#endif
}

std::atomic<int> g_parked_threads{0};  // _parked_threads(), for tests

// For a thread that must not return to Python because the interpreter is finalizing: sleeps
// until the process exits, touching nothing of Python's (its thread state may be freed already).
[[noreturn]] void park_forever() {
  g_parked_threads.fetch_add(1);
  for (;;) pause();
}

// Takes back the GIL released for a render, outside any destructor. During finalization Python
// ends a thread that asks for the GIL with pthread_exit, whose forced unwind aborted the process
// when it reached pybind11's gil_scoped_release destructor (noexcept): a daemon thread rendering
// while the interpreter exited died with "terminate called without an active exception" in 10
// runs of 10 (pybind11 issue 2215). Such a thread parks instead: when finalization has begun
// before it asks, or when the unwind arrives (finalization began in between). Its render is
// complete and its Renderer unlocked; the references it holds are never dropped.
void take_gil_or_park(PyThreadState* state) {
  if (interpreter_finalizing()) park_forever();
  try {
    PyEval_RestoreThread(state);
  } catch (abi::__forced_unwind&) {
    park_forever();  // not rethrown: the handler is never left
  }
}

// The last reference to a MeshData may go on a thread without the GIL (rendering releases it)
// => take the GIL to drop the Python references. Once the interpreter is shutting down, taking
// it could block or end the thread => leak them instead (the process is exiting), and park if
// finalization begins while asking for it (as take_gil_or_park; this runs in a noexcept deleter).
void release_owner(PyMeshOwner* owner) {
  if (PyGILState_Check()) {
    for (PyObject* obj : owner->viewed) Py_DECREF(obj);
  } else if (!owner->viewed.empty() && Py_IsInitialized() && !interpreter_finalizing()) {
    PyGILState_STATE gil;
    try {
      gil = PyGILState_Ensure();
    } catch (abi::__forced_unwind&) {
      park_forever();
    }
    for (PyObject* obj : owner->viewed) Py_DECREF(obj);
    PyGILState_Release(gil);
  }
  delete owner;
}

// The bytes object holding the `nbytes` that `arr` views, if nothing can ever write them; else
// null. NumPy refuses to make an array writeable whose chain of bases is read-only views ending
// in a bytes object, and bytes are immutable. A read-only array that owns its memory does not
// qualify: anyone may set it writeable again (and mutation after validation could send face
// indices out of range).
PyObject* immutable_bytes_base(const py::array& arr, std::size_t nbytes) {
  PyObject* obj = arr.ptr();
  while (py::isinstance<py::array>(py::handle(obj))) {
    auto view = py::reinterpret_borrow<py::array>(obj);
    if (view.writeable() || view.owndata()) return nullptr;
    obj = view.base().ptr();  // kept alive by the chain `arr` holds
    if (!obj) return nullptr;  // wraps foreign memory
  }
  if (!PyBytes_CheckExact(obj)) return nullptr;
  const char* begin = PyBytes_AS_STRING(obj);
  const char* data = static_cast<const char*>(arr.data());
  const std::size_t size = std::size_t(PyBytes_GET_SIZE(obj));
  return data >= begin && std::size_t(data - begin) + nbytes <= size ? obj : nullptr;
}

// A (n, cols) array of exactly dtype T as n V's (V = cols packed T's). Viewed in place when
// C-contiguous, aligned and immutable (its bytes object joins owner.viewed); else copied into
// `copy`, so no later write to the caller's array can reach a validated mesh.
template <typename T, typename V>
ConstSpan<V> rows_from_array(const py::handle& obj, const char* name, int cols,
                             std::vector<V>& copy, PyMeshOwner& owner) {
  const std::string arg(name);
  if (!py::isinstance<py::array>(obj)) throw py::type_error(arg + " must be a numpy array");
  auto arr = py::reinterpret_borrow<py::array>(obj);
  // dtypes are compared by value: an equal dtype need not be NumPy's cached instance (one that
  // was unpickled, or np.dtype('<f4')), while a byte-swapped '>f4' is unequal and refused.
  if (!arr.dtype().equal(py::dtype::of<T>()))
    throw py::type_error(arg + " must have dtype " + std::string(py::str(py::dtype::of<T>())) +
                         " (native byte order), got " + std::string(py::str(arr.dtype())));
  if (arr.ndim() != 2 || arr.shape(1) != cols)
    throw py::value_error(arg + " must have shape (n, " + std::to_string(cols) + ")");
  const std::size_t n = std::size_t(arr.shape(0));
  const bool in_place = (arr.flags() & py::array::c_style) &&
                        reinterpret_cast<std::uintptr_t>(arr.data()) % alignof(V) == 0;
  if (PyObject* bytes = in_place ? immutable_bytes_base(arr, n * sizeof(V)) : nullptr) {
    owner.viewed.push_back(bytes);
    Py_INCREF(bytes);
    return {static_cast<const V*>(arr.data()), n};
  }
  auto contiguous = py::array_t<T, py::array::c_style>::ensure(arr);
  copy.resize(n);
  if (n > 0) std::memcpy(copy.data(), contiguous.data(), n * sizeof(V));
  return view_of(copy);
}

dmat4 matrix_from_array(const py::handle& obj, const std::string& name) {
  if (!py::isinstance<py::array>(obj)) throw py::type_error(name + " must be a numpy array");
  auto arr = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!arr || arr.ndim() != 2 || arr.shape(0) != 4 || arr.shape(1) != 4)
    throw py::value_error(name + " must be a (4, 4) float64 array");
  dmat4 m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m[c][r] = arr.at(r, c);  // GLM is column-major
  return m;
}

std::shared_ptr<MeshData> make_mesh(const py::handle& positions, const py::handle& faces,
                                    const py::handle& normals, const py::handle& colors,
                                    const py::handle& uvs) {
  std::shared_ptr<PyMeshOwner> owner(new PyMeshOwner, release_owner);
  MeshVectors& copies = owner->copies;
  auto mesh = std::make_shared<MeshData>();
  mesh->positions = rows_from_array<float, vec3>(positions, "positions", 3, copies.positions, *owner);
  mesh->faces = rows_from_array<int32_t, ivec3>(faces, "faces", 3, copies.faces, *owner);
  if (!normals.is_none())
    mesh->normals = rows_from_array<float, vec3>(normals, "normals", 3, copies.normals, *owner);
  if (!colors.is_none())
    mesh->colors = rows_from_array<float, vec4>(colors, "colors", 4, copies.colors, *owner);
  if (!uvs.is_none()) mesh->uvs = rows_from_array<float, vec2>(uvs, "uvs", 2, copies.uvs, *owner);
  mesh->owner = std::move(owner);
  mesh->validate();
  return mesh;
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
      throw py::value_error("outputs: unknown output '" + name + "' (known: " + known + ")");
    }
    bits |= kOutputLayouts[found].bit;
  }
  if (bits == 0) throw py::value_error("outputs: request at least one output");
  return bits;
}

// Option names, the one place each is spelled; exported to Python (CULL_MODES, SHADING_MODELS,
// SHADING_PATHS, RASTER_ALGORITHMS), which checks a render's options against them before calling
// the core.
constexpr std::pair<const char*, Cull> kCullNames[] = {
    {"none", Cull::None}, {"back", Cull::Back}, {"front", Cull::Front}};
constexpr std::pair<const char*, ShadingPath> kShadingPathNames[] = {
    {"auto", ShadingPath::Auto}, {"forward", ShadingPath::Forward},
    {"deferred", ShadingPath::Deferred}};
constexpr std::pair<const char*, RasterAlgorithm> kRasterNames[] = {
    {"edge", RasterAlgorithm::Edge}, {"scanline", RasterAlgorithm::Scanline}};
constexpr std::pair<const char*, LineAlgorithm> kLineAlgorithmNames[] = {
    {"bresenham", LineAlgorithm::Bresenham}, {"dda", LineAlgorithm::Dda}};

// Reflectance models in Brdf's order (a material's record carries the index) and frequencies.
constexpr const char* kBrdfNames[] = {"unlit", "lambert", "phong", "blinn_phong", "pbr", "normal"};
constexpr std::pair<const char*, Frequency> kFrequencyNames[] = {
    {"pixel", Frequency::Pixel}, {"vertex", Frequency::Vertex}, {"face", Frequency::Face}};
// Texture filters and wrap modes, in their enums' order (texture.hpp; texture.py passes indices).
constexpr const char* kFilterNames[] = {"nearest", "bilinear", "trilinear", "anisotropic"};
constexpr const char* kWrapNames[] = {"repeat", "clamp", "mirror"};

template <typename E, std::size_t N>
E parse_name(const std::string& s, const std::pair<const char*, E> (&names)[N], const char* what) {
  for (const auto& [name, value] : names)
    if (s == name) return value;
  throw py::value_error(std::string(what) + ": unknown value '" + s + "'");
}

constexpr std::pair<const char*, Shading> kShadingNames[] = {
    {"unlit", Shading::Unlit}, {"lambert", Shading::Lambert}, {"normal", Shading::Normal},
    {"uv", Shading::Uv}, {"lit", Shading::Lit}};
Shading parse_shading(const std::string& s) { return parse_name(s, kShadingNames, "shading"); }

template <typename T, std::size_t N>
py::tuple names_of(const T (&items)[N]) {
  py::tuple t(N);
  for (std::size_t i = 0; i < N; ++i) t[i] = items[i].first;
  return t;
}

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

// A texture slot of a material record: a _core.Texture or None. The draws' records (and so the
// textures) stay referenced by the caller for the whole render.
const Texture* texture_from(const py::handle& h) {
  if (h.is_none()) return nullptr;
  return h.cast<Texture*>();
}

// A material record from render.py: (brdf index, kd_is_base, ka_is_kd, double_sided, ka, kd,
// ks, shininess, metallic, roughness, emissive, base_color_texture, emissive_texture,
// normal_texture, normal_scale, normal_y_down, metallic_roughness_texture, occlusion_texture,
// occlusion_strength, bump_texture, bump_scale, alpha_mask, alpha_cutoff); ranges are checked by
// Renderer::render.
Material material_from(const py::handle& h, const std::string& where) {
  auto t = py::reinterpret_borrow<py::tuple>(h);
  if (py::len(t) != 23) throw py::value_error(where + " material must have 23 fields");
  Material m;
  const int brdf = t[0].cast<int>();
  if (brdf < 0 || brdf >= int(std::size(kBrdfNames)))
    throw py::value_error(where + " material: unknown reflectance model");
  m.brdf = Brdf(brdf);
  m.kd_is_base = t[1].cast<bool>();
  m.ka_is_kd = t[2].cast<bool>();
  m.double_sided = t[3].cast<bool>();
  m.ka = vec3_from(t[4]);
  m.kd = vec3_from(t[5]);
  m.ks = vec3_from(t[6]);
  m.shininess = t[7].cast<float>();
  m.metallic = t[8].cast<float>();
  m.roughness = t[9].cast<float>();
  m.emissive = vec3_from(t[10]);
  m.base_color_texture = texture_from(t[11]);
  m.emissive_texture = texture_from(t[12]);
  m.normal_texture = texture_from(t[13]);
  m.normal_scale = t[14].cast<float>();
  m.normal_y_down = t[15].cast<bool>();
  m.metallic_roughness_texture = texture_from(t[16]);
  m.occlusion_texture = texture_from(t[17]);
  m.occlusion_strength = t[18].cast<float>();
  m.bump_texture = texture_from(t[19]);
  m.bump_scale = t[20].cast<float>();
  m.alpha_mask = t[21].cast<bool>();
  m.alpha_cutoff = t[22].cast<float>();
  if (m.emissive_texture) {  // the texture carries it, per pixel
    m.emissive_factor = m.emissive;
    m.emissive = vec3(0.0f);
  }
  return m;
}

// A light record (python/softrast/light.py, Light._core): (kind, radiance, position, direction,
// inverse_square, cone scale, cone offset), world space.
Light light_from(const py::handle& h) {
  auto t = py::reinterpret_borrow<py::tuple>(h);
  if (py::len(t) != 7) throw py::value_error("lights: a light record must have 7 fields");
  Light light;
  const int kind = t[0].cast<int>();
  if (kind < 0 || kind > int(LightKind::Spot)) throw py::value_error("lights: unknown light kind");
  light.kind = LightKind(kind);
  light.radiance = vec3_from(t[1]);
  light.position = vec3_from(t[2]);
  light.direction = vec3_from(t[3]);
  light.inverse_square = t[4].cast<bool>();
  light.cone_scale = t[5].cast<float>();
  light.cone_offset = t[6].cast<float>();
  return light;
}

// The render spec's keys, interned once (a dict lookup by a C string would build and hash a new
// Python string per key per render: about 1 us of a 6 us call).
enum SpecKey { k_view, k_proj, k_orthographic, k_near, k_far, k_outputs, k_cull, k_shading,
               k_shading_path, k_background, k_ambient, k_out, k_lights, k_ambient_light,
               k_frequency, k_srgb, k_texture_filter, k_normal_rotation, k_raster, k_msaa, k_ssaa,
               k_primitives, k_line_algorithm, kNumSpecKeys };
constexpr const char* kSpecKeys[kNumSpecKeys] = {
    "view", "proj", "orthographic", "near", "far", "outputs", "cull", "shading",
    "shading_path", "background", "ambient", "out", "lights", "ambient_light", "frequency",
    "srgb", "texture_filter", "normal_rotation", "raster", "msaa", "ssaa", "primitives",
    "line_algorithm"};
PyObject* spec_key(SpecKey key) {
  // Made on first use with the GIL held and never freed (they live as long as the interpreter).
  static PyObject* const* const keys = [] {
    static PyObject* made[kNumSpecKeys];
    for (int i = 0; i < kNumSpecKeys; ++i) made[i] = PyUnicode_InternFromString(kSpecKeys[i]);
    return made;
  }();
  return keys[key];
}

// The rows of a (n, cols) C-contiguous array of exactly dtype T, viewed (not copied): the caller
// keeps the array alive and unchanged during the render (Lines and Points hold read-only copies).
template <typename T, typename V>
ConstSpan<V> view_rows(const py::handle& obj, const std::string& name, int cols) {
  if (!py::isinstance<py::array>(obj)) throw py::type_error(name + " must be a numpy array");
  auto arr = py::reinterpret_borrow<py::array>(obj);
  if (!arr.dtype().equal(py::dtype::of<T>()) || arr.ndim() != 2 || arr.shape(1) != cols ||
      !(arr.flags() & py::array::c_style) ||
      reinterpret_cast<std::uintptr_t>(arr.data()) % alignof(T) != 0)
    throw py::value_error(name + " must be a C-contiguous " + std::string(py::str(py::dtype::of<T>())) +
                          " array with shape (n, " + std::to_string(cols) + ")");
  return {static_cast<const V*>(arr.data()), std::size_t(arr.shape(0))};
}

// A Lines or Points record from render.py: (points, positions, segments or None, colors or None,
// rgb, width or size, pose, instance_id[, depth_bias]).
PrimitiveDraw primitive_from(const py::handle& obj, const std::string& where) {
  auto item = py::reinterpret_borrow<py::tuple>(obj);
  if (py::len(item) != 8 && py::len(item) != 9)
    throw py::value_error(where + " must be (points, positions, segments, colors, rgb, width, pose, "
                          "instance_id)");
  PrimitiveDraw d;
  d.points = item[0].cast<bool>();
  d.positions = view_rows<float, vec3>(item[1], where + " positions", 3);
  if (!item[2].is_none()) d.segments = view_rows<int32_t, glm::ivec2>(item[2], where + " segments", 2);
  if (!item[3].is_none()) d.colors = view_rows<float, vec3>(item[3], where + " colors", 3);
  const auto rgb = item[4].cast<std::array<float, 3>>();
  d.color = vec3(rgb[0], rgb[1], rgb[2]);
  d.width = item[5].cast<float>();
  d.model = matrix_from_array(item[6], where + " pose");
  d.instance_id = item[7].cast<int32_t>();
  if (py::len(item) == 9) d.depth_bias = item[8].cast<float>();
  return d;
}

// One render, as one spec from render.py, which has checked every option by name: only what
// Python cannot check (array memory, overlaps) or the core needs for safety is checked here
// and in Renderer::render. Keys: view, proj (4x4 float64), orthographic, near, far, outputs
// (names), cull, shading, shading_path, raster (names), background (3 floats), ambient, out (dict
// of arrays or None), and optionally msaa, ssaa (ints, default 1).
py::dict render(Renderer& self, const py::sequence& draws_in, const py::dict& spec) {
  std::vector<Draw> draws;
  for (std::size_t d = 0; d < py::len(draws_in); ++d) {
    const std::string where = "draws[" + std::to_string(d) + "]";
    auto item = py::reinterpret_borrow<py::tuple>(draws_in[d]);
    if (py::len(item) != 5)
      throw py::value_error(where + " must be (mesh, model, instance_id, rgba, material)");
    Draw draw;
    draw.mesh = item[0].cast<std::shared_ptr<MeshData>>();
    draw.model = matrix_from_array(item[1], where + " pose");
    draw.instance_id = item[2].cast<int32_t>();
    const auto rgba = item[3].cast<std::array<float, 4>>();
    draw.color = vec4(rgba[0], rgba[1], rgba[2], rgba[3]);
    draw.material = material_from(item[4], where);
    draws.push_back(std::move(draw));
  }
  const auto get = [&](SpecKey key) -> py::object {
    PyObject* value = PyDict_GetItem(spec.ptr(), spec_key(key));  // borrowed; no error set
    if (!value) throw py::key_error(std::string("render spec has no '") + kSpecKeys[key] + "'");
    return py::reinterpret_borrow<py::object>(value);
  };
  CameraParams camera;
  camera.view = matrix_from_array(get(k_view), "view");
  camera.proj = matrix_from_array(get(k_proj), "proj");
  camera.orthographic = get(k_orthographic).cast<bool>();
  camera.near = get(k_near).cast<double>();
  camera.far = get(k_far).cast<double>();
  RenderOptions options;
  options.outputs = parse_outputs(get(k_outputs).cast<std::vector<std::string>>());
  options.cull = parse_name(get(k_cull).cast<std::string>(), kCullNames, "cull");
  options.shading = parse_shading(get(k_shading).cast<std::string>());
  options.shading_path = parse_name(get(k_shading_path).cast<std::string>(), kShadingPathNames, "shading_path");
  options.raster = parse_name(get(k_raster).cast<std::string>(), kRasterNames, "raster");
  const auto background = get(k_background).cast<std::array<float, 3>>();
  for (int c = 0; c < 3; ++c) options.background[c] = background[c];  // range: Renderer::render
  options.ambient = get(k_ambient).cast<float>();
  for (const py::handle light : get(k_lights)) options.lights.push_back(light_from(light));
  options.ambient_light = vec3_from(get(k_ambient_light));
  options.frequency = parse_name(get(k_frequency).cast<std::string>(), kFrequencyNames, "frequency");
  options.srgb = get(k_srgb).cast<bool>();
  const int filter = get(k_texture_filter).cast<int>();  // -1: each texture's own
  if (filter >= int(std::size(kFilterNames))) throw py::value_error("texture_filter: unknown filter");
  options.texture_filter = filter < 0 ? kNoFilterOverride : uint8_t(filter);
  // Anti-aliasing, optional (1: off); counts are checked by Renderer::render.
  for (const SpecKey key : {k_msaa, k_ssaa}) {
    PyObject* value = PyDict_GetItem(spec.ptr(), spec_key(key));
    if (value) (key == k_msaa ? options.msaa : options.ssaa) = py::handle(value).cast<int>();
  }
  // Lines and points, optional (none), and how lines are stepped (default Bresenham).
  std::vector<PrimitiveDraw> primitives;
  LineAlgorithm line_algorithm = LineAlgorithm::Bresenham;
  if (PyObject* value = PyDict_GetItem(spec.ptr(), spec_key(k_primitives))) {
    std::size_t index = 0;
    for (const py::handle item : py::handle(value))
      primitives.push_back(primitive_from(item, "primitives[" + std::to_string(index++) + "]"));
  }
  if (PyObject* value = PyDict_GetItem(spec.ptr(), spec_key(k_line_algorithm)))
    line_algorithm = parse_name(py::handle(value).cast<std::string>(), kLineAlgorithmNames,
                                "line_algorithm");
  const py::object rotation = get(k_normal_rotation);  // None: world space
  if (!rotation.is_none()) {
    const auto r = rotation.cast<std::array<std::array<float, 3>, 3>>();  // rows
    options.normal_camera = true;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) options.normal_rotation[j][i] = r[i][j];  // glm: [column][row]
  }
  // Mip chains, built once per texture, for the textures whose filter needs them.
  std::vector<Texture*> need_mips;
  for (const Draw& d : draws)
    for (const Texture* t : {d.material.base_color_texture, d.material.emissive_texture,
                             d.material.normal_texture, d.material.metallic_roughness_texture,
                             d.material.occlusion_texture, d.material.bump_texture})
      if (t && !t->has_mips()) {
        const TextureFilter f = filter < 0 ? t->filter : TextureFilter(filter);
        if (f == TextureFilter::Trilinear || f == TextureFilter::Anisotropic)
          need_mips.push_back(const_cast<Texture*>(t));
      }
  const py::object out = get(k_out);

  // Caller-supplied arrays (out=) are written in place; `out` keeps them alive meanwhile.
  std::byte* external[kNumOutputs] = {};
  py::dict out_dict = out.is_none() ? py::dict() : py::dict(out);
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

// -- lens distortion (python/softrast/distortion.py): the per-pixel passes ---------------------
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
}  // namespace sr

PYBIND11_MODULE(_core, m) {
  using namespace sr;
  m.doc() = "softrast's C++ core (private: use the softrast package).";
  // Load NumPy's C API at import, as extension modules conventionally do: pybind11 otherwise
  // loads it on first use (~0.1 ms of imports and version checks), in the first mesh upload.
  (void)py::dtype::of<float>();
  m.attr("SUBPIXEL_BITS") = kSubpixelBits;
  m.attr("TILE_SIZE_PX") = kTileSizePx;
  m.attr("MAX_IMAGE_SIDE") = kMaxImageSide;
  m.attr("MAX_FRAMEBUFFER_BYTES") = py::int_(kMaxFramebufferBytes);
  m.attr("MAX_THREADS") = kMaxThreads;
  // The output table (framebuffer.hpp), the one source of every list of outputs in Python.
  py::tuple names(kNumOutputs), table(kNumOutputs);
  for (int i = 0; i < kNumOutputs; ++i) {
    const OutputLayout& l = kOutputLayouts[i];
    names[i] = l.name;
    py::dict row;
    row["name"] = l.name;
    row["dtype"] = output_dtype(l);
    row["channels"] = l.channels;
    row["bytes_per_pixel"] = l.bytes_per_pixel();
    row["background"] = l.background;
    row["pass"] = l.pass == OutputPass::Shade ? "shade" : l.pass == OutputPass::Surface ? "surface" : "resolve";
    row["doc"] = l.doc;
    table[i] = row;
  }
  m.attr("OUTPUTS") = names;
  m.attr("OUTPUT_TABLE") = table;
  m.attr("SHADING_MODELS") = names_of(kShadingNames);
  m.attr("CULL_MODES") = names_of(kCullNames);
  m.attr("SHADING_PATHS") = names_of(kShadingPathNames);
  m.attr("RASTER_ALGORITHMS") = names_of(kRasterNames);
  m.attr("LINE_ALGORITHMS") = names_of(kLineAlgorithmNames);
  m.attr("FREQUENCIES") = names_of(kFrequencyNames);
  py::tuple brdfs(std::size(kBrdfNames));
  for (std::size_t i = 0; i < std::size(kBrdfNames); ++i) brdfs[i] = kBrdfNames[i];
  m.attr("REFLECTANCE_MODELS") = brdfs;

  py::tuple filters(std::size(kFilterNames)), wraps(std::size(kWrapNames));
  for (std::size_t i = 0; i < std::size(kFilterNames); ++i) filters[i] = kFilterNames[i];
  for (std::size_t i = 0; i < std::size(kWrapNames); ++i) wraps[i] = kWrapNames[i];
  m.attr("TEXTURE_FILTERS") = filters;
  m.attr("TEXTURE_WRAPS") = wraps;

  // A texture's level 0 views the array (kept alive by the Texture); python/softrast/texture.py
  // checks and converts the image (uint8 as is, anything else to linear float32) and the options.
  py::class_<Texture, std::shared_ptr<Texture>>(m, "Texture")
      .def(py::init([](py::array_t<uint8_t, 0> image, bool srgb) {
             if (image.ndim() != 3 || !(image.flags() & py::array::c_style))
               throw py::value_error("image must be a C-contiguous (h, w, c) array");
             return std::make_shared<Texture>(int(image.shape(1)), int(image.shape(0)),
                                              int(image.shape(2)), image.data(), srgb);
           }),
           "image"_a, "srgb"_a, py::keep_alive<1, 2>())
      .def(py::init([](py::array_t<float, 0> image) {
             if (image.ndim() != 3 || !(image.flags() & py::array::c_style))
               throw py::value_error("image must be a C-contiguous (h, w, c) array");
             return std::make_shared<Texture>(int(image.shape(1)), int(image.shape(0)),
                                              int(image.shape(2)), image.data());
           }),
           "image"_a, py::keep_alive<1, 2>())
      .def("configure",
           [](Texture& t, int filter, int wrap_u, int wrap_v, bool top_left, int max_anisotropy) {
             if (filter < 0 || filter >= int(std::size(kFilterNames)) || wrap_u < 0 ||
                 wrap_u >= int(std::size(kWrapNames)) || wrap_v < 0 ||
                 wrap_v >= int(std::size(kWrapNames)) || max_anisotropy < 1)
               throw py::value_error("Texture.configure: bad option");
             t.filter = TextureFilter(filter);
             t.wrap_u = Wrap(wrap_u);
             t.wrap_v = Wrap(wrap_v);
             t.top_left = top_left;
             t.max_anisotropy = max_anisotropy;
           },
           "filter"_a, "wrap_u"_a, "wrap_v"_a, "top_left"_a, "max_anisotropy"_a)
      .def("build_mips", &Texture::build_mips, py::call_guard<py::gil_scoped_release>())
      .def_property_readonly("has_mips", &Texture::has_mips)
      .def_property_readonly("num_levels", &Texture::num_levels)
      .def("level_size", [](const Texture& t, int l) {
             if (l < 0 || l >= t.num_levels()) throw py::index_error("level out of range");
             return py::make_tuple(t.level_height(l), t.level_width(l));
           })
      .def("mip", [](Texture& t, int l) {
             if (l < 0 || l >= t.num_levels()) throw py::index_error("level out of range");
             if (l > 0) t.build_mips();
             const int w = t.level_width(l), h = t.level_height(l);
             py::array_t<float> out({h, w, 4});
             float* p = out.mutable_data();
             for (int y = 0; y < h; ++y)
               for (int x = 0; x < w; ++x) {
                 const vec4 v = t.texel(l, x, y);
                 for (int c = 0; c < 4; ++c) p[(std::size_t(y) * w + x) * 4 + c] = v[c];
               }
             return out;
           }, "level"_a)
      .def("sample",
           [](Texture& t, py::array_t<float, py::array::c_style> uv,
              py::array_t<float, py::array::c_style> duv, int filter) {
             if (filter < 0 || filter >= int(std::size(kFilterNames)))
               throw py::value_error("filter: unknown filter");
             if (uv.ndim() != 2 || uv.shape(1) != 2 || duv.ndim() != 2 || duv.shape(1) != 4 ||
                 duv.shape(0) != uv.shape(0))
               throw py::value_error("uv must be (n, 2) and duv (n, 4)");
             const TextureFilter f = TextureFilter(filter);
             const std::size_t n = std::size_t(uv.shape(0));
             py::array_t<float> out({py::ssize_t(n), py::ssize_t(4)});
             const float* a = uv.data();
             const float* d = duv.data();
             float* o = out.mutable_data();
             {
               py::gil_scoped_release release;
               if (f == TextureFilter::Trilinear || f == TextureFilter::Anisotropic) t.build_mips();
               for (std::size_t i = 0; i < n; ++i) {
                 const vec4 s = sample_texture(t, f, a[2 * i], a[2 * i + 1], d[4 * i], d[4 * i + 1],
                                               d[4 * i + 2], d[4 * i + 3]);
                 for (int c = 0; c < 4; ++c) o[4 * i + c] = s[c];
               }
             }
             return out;
           },
           "uv"_a, "duv"_a, "filter"_a,
           "Samples at n points: (n, 2) uv, (n, 4) derivatives (du/dx, dv/dx, du/dy, dv/dy); "
           "(n, 4) linear RGBA, exactly what a render reads.");

  py::class_<MeshData, std::shared_ptr<MeshData>>(m, "MeshData")
      .def(py::init(&make_mesh), "positions"_a, "faces"_a, "normals"_a = py::none(),
           "colors"_a = py::none(), "uvs"_a = py::none(),
           "Validates (n,3) float32 positions, (m,3) int32 faces and optional (n,3) float32 "
           "normals, (n,4) float32 colors, (n,2) float32 uvs. Views immutable arrays (read-only "
           "views of a bytes object) in place and copies any other.")
      .def_property_readonly("num_vertices", [](const MeshData& m) { return m.positions.size(); })
      .def_property_readonly("num_faces", [](const MeshData& m) { return m.faces.size(); });

  // Lens distortion's per-pixel passes (python/softrast/distortion.py), hence the underscores.
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

  // Testing only (tests/test_lifecycle.py), hence the underscores.
  m.def("_fail_thread_start", &fail_thread_start, "n"_a,
        "The n-th worker thread started from now on (1 = the next) fails as if the system had "
        "refused it; 0 = off.");
  m.def("_parked_threads", [] { return g_parked_threads.load(); },
        "Threads parked for good because they finished a render while the interpreter finalized.");

  // ValueError for threads outside [0, MAX_THREADS] (std::invalid_argument), RuntimeError naming
  // `threads` when the system refuses a worker thread (std::runtime_error; none is left running).
  py::class_<Renderer>(m, "Renderer")
      .def(py::init<int, int, int, bool>(), "width"_a, "height"_a, "threads"_a = 0, "simd"_a = true)
      .def_property_readonly("width", &Renderer::width)
      .def_property_readonly("height", &Renderer::height)
      .def_property_readonly("threads", &Renderer::threads)
      .def_property_readonly("isa", [](const Renderer& r) { return isa_name(r.isa()); })
      .def("render", &render, "draws"_a, "spec"_a);
}
