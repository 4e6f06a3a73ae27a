// Python bindings, by what they bind (the only files that include pybind11): module.cpp (the
// module, its constants and option names), mesh.cpp (geometry uploaded without copies),
// texture.cpp, records.cpp (materials, lights, draws, lines and points as named records),
// render.cpp (a render: its options by name, the GIL, framebuffers handed over without copies),
// distortion.cpp (lens distortion's per-pixel passes), encode.cpp (image files for datasets),
// clip_raster.cpp (triangles given in clip space, for softrast.nv). Each file's bind_* adds its part.
//
// Records cross the binding with named fields (Record below), each field checked when it is set;
// the render's options are a dict read by name (render.cpp). Both tables are exported
// (_core.RECORDS, _core.RENDER_OPTIONS), and python/softrast/_stubgen.py writes _core.pyi from
// them and from pybind11's own signatures: the stub cannot drift from these files.
#pragma once

#include "../framebuffer.hpp"
#include "../materials.hpp"
#include "../pipeline.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <functional>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <vector>

namespace sr {
namespace bind {

namespace py = pybind11;

void bind_mesh(py::module_& m);
void bind_texture(py::module_& m);
void bind_records(py::module_& m);
void bind_render(py::module_& m);
void bind_distortion(py::module_& m);
void bind_encode(py::module_& m);
void bind_clip_raster(py::module_& m);

// Names of option values, the one place each is spelled (module.cpp); exported to Python
// (CULL_MODES, SHADING_MODELS, ...), which checks a render's options against them.
template <typename E>
struct Name {
  const char* name;
  E value;
};
extern const Name<Cull> kCullNames[3];
extern const Name<Shading> kShadingNames[kNumShadings];
extern const Name<Brdf> kModelNames[kNumMaterialModels];  // a material's models
extern const Name<Frequency> kFrequencyNames[3];
extern const Name<ShadingPath> kShadingPathNames[3];
extern const Name<RasterAlgorithm> kRasterNames[2];
extern const Name<int> kLineAlgorithmNames[2];  // LineAlgorithm (lines.hpp)
extern const Name<int> kNormalKindNames[2];      // 1: RenderOptions::shading_normals
extern const Name<int> kFilterNames[4];          // TextureFilter (texture.hpp)
extern const Name<int> kWrapNames[3];            // Wrap (texture.hpp)
extern const Name<LightKind> kLightKindNames[3];
extern const Name<ShadowMethod> kShadowMethodNames[3];

// The value named `s` in `names`, or ValueError naming `what` and the choices.
template <typename E, std::size_t N>
E parse_name(const std::string& s, const Name<E> (&names)[N], const char* what) {
  for (const Name<E>& n : names)
    if (s == n.name) return n.value;
  std::string known;
  for (const Name<E>& n : names) known += std::string(known.empty() ? "" : ", ") + n.name;
  throw py::value_error(std::string(what) + ": unknown value '" + s + "' (one of " + known + ")");
}
template <typename E, std::size_t N>
py::tuple names_of(const Name<E> (&names)[N]) {
  py::tuple t(N);
  for (std::size_t i = 0; i < N; ++i) t[i] = names[i].name;
  return t;
}
template <typename E, std::size_t N>
const char* name_of(E value, const Name<E> (&names)[N]) {
  for (const Name<E>& n : names)
    if (n.value == value) return n.name;
  return "?";
}

// An output's NumPy dtype (render.cpp).
py::dtype output_dtype(const sr::OutputLayout& layout);

// A (4, 4) array as a matrix (float64, GLM's column-major order); TypeError / ValueError naming
// `name` otherwise.
dmat4 matrix_from_array(const py::handle& obj, const std::string& name);
py::array matrix_to_array(const dmat4& m);

// One documented field of a record or option: its name, its Python type (for the stub) and doc.
struct FieldDoc {
  std::string name, type, doc;
};
// The exported tables (module.cpp): record name -> its fields, in order.
py::dict& record_docs();

// A record class with named fields: made with keyword arguments (every one optional, each
// converted and checked once, unknown names refused), read back as properties, and documented
// in record_docs() for the stub. R is a C++ struct; fields are get / set function pairs.
// Compile time: every field is type-erased to the same two signatures (py::object get(const R&),
// void set(R&, handle)), so pybind11's function machinery is instantiated once per record, not
// once per (record, field type): that halved the bindings' compile time.
template <typename R>
class Record {
 public:
  Record(py::module_& m, const char* name, const char* doc) : cls_(m, name, doc), name_(name) {}
  using Class = py::class_<R, std::shared_ptr<R>>;

  template <typename V>
  Record& field(const char* name, const char* type, const char* doc, V (*get)(const R&),
                void (*set)(R&, V)) {
    const std::string record = name_, field_name = name;
    fields_->push_back(
        {name,
         [get](const R& r) -> py::object {
           if constexpr (std::is_base_of_v<py::handle, V>) return get(r);
           else return py::cast(get(r));
         },
         [set, record, field_name, type](R& r, py::handle value) {
           V v;
           try {
             v = value.cast<V>();
           } catch (const py::cast_error&) {
             throw py::type_error(record + ": " + field_name + " must be " + type + ", got " +
                                  std::string(py::str(py::type::of(value).attr("__name__"))));
           }
           set(r, v);
         }});
    docs_.push_back({name, type, doc});
    return *this;
  }

  // Defines the properties and __init__(**fields), and registers the documentation.
  void finish() {
    auto fields = fields_;
    for (std::size_t i = 0; i < fields->size(); ++i) {
      cls_.def_property(
          (*fields)[i].name.c_str(),
          py::cpp_function([fields, i](const R& r) { return (*fields)[i].get(r); }),
          py::cpp_function([fields, i](R& r, py::handle v) { (*fields)[i].set(r, v); }),
          docs_[i].doc.c_str());
    }
    const std::string record = name_;
    cls_.def(py::init([fields, record](const py::kwargs& kwargs) {
               auto r = std::make_shared<R>();
               for (const auto& [key, value] : kwargs) {
                 const std::string k = py::str(key);
                 const Field* f = nullptr;
                 for (const Field& candidate : *fields)
                   if (candidate.name == k) f = &candidate;
                 if (!f) throw py::type_error(record + ": unknown field '" + k + "'");
                 f->set(*r, value);
               }
               return r;
             }),
             ("A " + record + " record: every field by name (unset fields keep their defaults).")
                 .c_str());
    py::list docs;
    for (const FieldDoc& f : docs_) docs.append(py::make_tuple(f.name, f.type, f.doc));
    record_docs()[name_.c_str()] = docs;
  }

  Class& cls() { return cls_; }

 private:
  struct Field {
    std::string name;
    std::function<py::object(const R&)> get;
    std::function<void(R&, py::handle)> set;
  };
  Class cls_;
  std::string name_;
  std::shared_ptr<std::vector<Field>> fields_ = std::make_shared<std::vector<Field>>();
  std::vector<FieldDoc> docs_;
};

}  // namespace bind
}  // namespace sr
