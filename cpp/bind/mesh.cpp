// Bindings: meshes. A MeshData views the caller's arrays without copying them where they are
// immutable (softrast.Mesh stores them so), and copies any other, then validates once.
#include "bind.hpp"
#include "gil.hpp"

#include <cstdint>
#include <cstring>

namespace sr {
namespace bind {

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

}  // namespace

void bind_mesh(py::module_& m) {
  py::class_<MeshData, std::shared_ptr<MeshData>>(m, "MeshData")
      .def(py::init(&make_mesh), py::arg("positions"), py::arg("faces"), py::arg("normals") = py::none(),
           py::arg("colors") = py::none(), py::arg("uvs") = py::none(),
           "Validates (n,3) float32 positions, (m,3) int32 faces and optional (n,3) float32 "
           "normals, (n,4) float32 colors, (n,2) float32 uvs. Views immutable arrays (read-only "
           "views of a bytes object) in place and copies any other.")
      .def_property_readonly("num_vertices", [](const MeshData& m) { return m.positions.size(); })
      .def_property_readonly("num_faces", [](const MeshData& m) { return m.faces.size(); });

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

py::array matrix_to_array(const dmat4& m) {
  py::array_t<double> out({4, 4});
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out.mutable_at(r, c) = m[c][r];
  return out;
}

}  // namespace bind
}  // namespace sr
