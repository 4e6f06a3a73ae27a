// Bindings: the records a scene hands the core, with named fields (bind.hpp, Record): a material,
// a light, a draw (mesh instance) and a line or point set. Each is made once (materials and draws
// are cached by the Python scene) and read by a render without parsing.
#include "records.hpp"

#include "../shadow.hpp"
#include "../texture.hpp"

#include <array>

namespace sr {
namespace bind {

namespace {

using Rgb = std::array<float, 3>;
using Rgba = std::array<float, 4>;
Rgb rgb(const vec3& v) { return {v.x, v.y, v.z}; }
vec3 vec(const Rgb& v) { return vec3(v[0], v[1], v[2]); }

// A texture slot: a _core.Texture or None.
std::shared_ptr<Texture> texture_or_none(const py::object& value, const char* field) {
  if (value.is_none()) return nullptr;
  if (!py::isinstance<Texture>(value))
    throw py::type_error(std::string("Material: ") + field + " must be a Texture or None");
  return value.cast<std::shared_ptr<Texture>>();
}

// The rows of a (n, cols) C-contiguous array of exactly dtype T, viewed (not copied): the record
// keeps the array alive, and Lines and Points hold read-only copies.
template <typename T, typename V>
ConstSpan<V> view_rows(const py::object& obj, const std::string& name, int cols) {
  if (!py::isinstance<py::array>(obj)) throw py::type_error(name + " must be a numpy array");
  auto arr = py::reinterpret_borrow<py::array>(obj);
  if (!arr.dtype().equal(py::dtype::of<T>()) || arr.ndim() != 2 || arr.shape(1) != cols ||
      !(arr.flags() & py::array::c_style) ||
      reinterpret_cast<std::uintptr_t>(arr.data()) % alignof(T) != 0)
    throw py::value_error(name + " must be a C-contiguous " + std::string(py::str(py::dtype::of<T>())) +
                          " array with shape (n, " + std::to_string(cols) + ")");
  return {static_cast<const V*>(arr.data()), std::size_t(arr.shape(0))};
}

// A texture slot of a material: a Texture or None, kept alive by the record.
#define SR_TEXTURE_FIELD(slot, doc)                                                        \
  .field<py::object>(                                                                      \
      #slot, "Texture | None", doc,                                                        \
      +[](const MaterialRecord& r) -> py::object {                                         \
        const auto& t = r.textures[MaterialRecord::k_##slot];                              \
        return t ? py::cast(t) : py::none();                                               \
      },                                                                                   \
      +[](MaterialRecord& r, py::object v) {                                               \
        r.textures[MaterialRecord::k_##slot] = texture_or_none(v, #slot);                  \
        r.material.slot = r.textures[MaterialRecord::k_##slot].get();                      \
      })

void bind_material(py::module_& m) {
  Record<MaterialRecord>(m, "Material",
                         "A material (python/softrast/material.py states each field's meaning).")
      .field<std::string>(
          "model", "str", "its reflectance model (REFLECTANCE_MODELS), drawn by shading='auto'",
          +[](const MaterialRecord& r) { return std::string(name_of(r.material.model, kModelNames)); },
          +[](MaterialRecord& r, std::string v) { r.material.model = parse_name(v, kModelNames, "Material: model"); })
      .field<bool>("kd_is_base", "bool", "kd is the base colour (vertex colours, else the draw's colour)",
          +[](const MaterialRecord& r) { return r.material.kd_is_base; },
          +[](MaterialRecord& r, bool v) { r.material.kd_is_base = v; })
      .field<bool>("ka_is_kd", "bool", "ka is kd",
          +[](const MaterialRecord& r) { return r.material.ka_is_kd; },
          +[](MaterialRecord& r, bool v) { r.material.ka_is_kd = v; })
      .field<bool>("double_sided", "bool", "back faces are lit as front faces (else dark side)",
          +[](const MaterialRecord& r) { return r.material.double_sided; },
          +[](MaterialRecord& r, bool v) { r.material.double_sided = v; })
      .field<Rgb>("ka", "tuple[float, float, float]", "ambient reflectance (unless ka_is_kd)",
          +[](const MaterialRecord& r) { return rgb(r.material.ka); },
          +[](MaterialRecord& r, Rgb v) { r.material.ka = vec(v); })
      .field<Rgb>("kd", "tuple[float, float, float]", "diffuse reflectance (unless kd_is_base)",
          +[](const MaterialRecord& r) { return rgb(r.material.kd); },
          +[](MaterialRecord& r, Rgb v) { r.material.kd = vec(v); })
      .field<Rgb>("ks", "tuple[float, float, float]", "specular reflectance (phong, blinn_phong)",
          +[](const MaterialRecord& r) { return rgb(r.material.ks); },
          +[](MaterialRecord& r, Rgb v) { r.material.ks = vec(v); })
      .field<float>("shininess", "float", "the specular exponent, >= 0",
          +[](const MaterialRecord& r) { return r.material.shininess; },
          +[](MaterialRecord& r, float v) { r.material.shininess = v; })
      .field<float>("metallic", "float", "pbr: in [0, 1]",
          +[](const MaterialRecord& r) { return r.material.metallic; },
          +[](MaterialRecord& r, float v) { r.material.metallic = v; })
      .field<float>("roughness", "float", "pbr: in [0, 1]",
          +[](const MaterialRecord& r) { return r.material.roughness; },
          +[](MaterialRecord& r, float v) { r.material.roughness = v; })
      .field<Rgb>("emissive", "tuple[float, float, float]",
          "added radiance (times the emissive texture where there is one)",
          +[](const MaterialRecord& r) { return rgb(r.emissive); },
          +[](MaterialRecord& r, Rgb v) { r.emissive = vec(v); })
      SR_TEXTURE_FIELD(base_color_texture, "multiplies the base colour (rgb)")
      SR_TEXTURE_FIELD(emissive_texture, "emissive times its rgb is added")
      SR_TEXTURE_FIELD(normal_texture, "tangent-space normals")
      .field<float>("normal_scale", "float", "scales the normal texture's x and y",
          +[](const MaterialRecord& r) { return r.material.normal_scale; },
          +[](MaterialRecord& r, float v) { r.material.normal_scale = v; })
      .field<bool>("normal_y_down", "bool", "a DirectX-style normal texture (green = -v)",
          +[](const MaterialRecord& r) { return r.material.normal_y_down; },
          +[](MaterialRecord& r, bool v) { r.material.normal_y_down = v; })
      SR_TEXTURE_FIELD(metallic_roughness_texture, "glTF: green * roughness, blue * metallic")
      SR_TEXTURE_FIELD(occlusion_texture, "red: ambient *= 1 + strength (red - 1)")
      .field<float>("occlusion_strength", "float", "in [0, 1]",
          +[](const MaterialRecord& r) { return r.material.occlusion_strength; },
          +[](MaterialRecord& r, float v) { r.material.occlusion_strength = v; })
      SR_TEXTURE_FIELD(bump_texture, "a height map (its first channel)")
      SR_TEXTURE_FIELD(specular_texture, "rgb scales ks (phong, blinn_phong)")
      .field<float>("bump_scale", "float", "the bump texture's height scale",
          +[](const MaterialRecord& r) { return r.material.bump_scale; },
          +[](MaterialRecord& r, float v) { r.material.bump_scale = v; })
      .field<bool>("alpha_mask", "bool", "glTF alphaMode MASK: fragments below alpha_cutoff are discarded",
          +[](const MaterialRecord& r) { return r.material.alpha_mask; },
          +[](MaterialRecord& r, bool v) { r.material.alpha_mask = v; })
      .field<float>("alpha_cutoff", "float", "alpha_mask's threshold",
          +[](const MaterialRecord& r) { return r.material.alpha_cutoff; },
          +[](MaterialRecord& r, float v) { r.material.alpha_cutoff = v; })
      .field<bool>("alpha_blend", "bool",
          "glTF alphaMode BLEND: composited in depth order over what lies behind (not with alpha_mask)",
          +[](const MaterialRecord& r) { return r.material.alpha_blend; },
          +[](MaterialRecord& r, bool v) { r.material.alpha_blend = v; })
      .finish();
}
#undef SR_TEXTURE_FIELD

void attach_shadow_map(Light& light, const py::list& faces, double bias);

void bind_light(py::module_& m) {
  Record<Light>(m, "Light", "A light in world space (python/softrast/light.py).")
      .field<std::string>("kind", "str", "'directional', 'point' or 'spot'",
          +[](const Light& l) { return std::string(name_of(l.kind, kLightKindNames)); },
          +[](Light& l, std::string v) { l.kind = parse_name(v, kLightKindNames, "Light: kind"); })
      .field<Rgb>("radiance", "tuple[float, float, float]", "colour times intensity, linear",
          +[](const Light& l) { return rgb(l.radiance); },
          +[](Light& l, Rgb v) { l.radiance = vec(v); })
      .field<Rgb>("position", "tuple[float, float, float]", "point and spot lights",
          +[](const Light& l) { return rgb(l.position); },
          +[](Light& l, Rgb v) { l.position = vec(v); })
      .field<Rgb>("direction", "tuple[float, float, float]", "unit: the direction the light travels",
          +[](const Light& l) { return rgb(l.direction); },
          +[](Light& l, Rgb v) { l.direction = vec(v); })
      .field<bool>("inverse_square", "bool", "point and spot: radiance / r^2",
          +[](const Light& l) { return l.inverse_square; },
          +[](Light& l, bool v) { l.inverse_square = v; })
      .field<float>("cone_scale", "float", "spot: clamp(cos * cone_scale + cone_offset, 0, 1)^2",
          +[](const Light& l) { return l.cone_scale; },
          +[](Light& l, float v) { l.cone_scale = v; })
      .field<float>("cone_offset", "float", "spot: see cone_scale",
          +[](const Light& l) { return l.cone_offset; },
          +[](Light& l, float v) { l.cone_offset = v; })
      .field<std::string>("shadow", "str", "'none', 'exact' or 'map' (cpp/shadow.hpp)",
          +[](const Light& l) { return std::string(name_of(l.shadow, kShadowMethodNames)); },
          +[](Light& l, std::string v) { l.shadow = parse_name(v, kShadowMethodNames, "Light: shadow"); })
      .finish();
  m.def("_attach_shadow_map", &attach_shadow_map, py::arg("light"), py::arg("faces"), py::arg("bias"),
        "Gives a light record its shadow maps (python/softrast/shadow_maps.py): faces of "
        "(view, proj, orthographic, depth); the depth maps are copied.");
}

// A light's shadow maps (python/softrast/shadow_maps.py): faces of (view, proj, orthographic,
// depth), view and proj (4, 4) float64 row-major, depth (n, n) float32; copied.
void attach_shadow_map(Light& light, const py::list& faces, double bias) {
  auto map = std::make_shared<ShadowMap>();
  map->bias = bias;
  const auto mat = [](const py::handle& obj) {
    auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
    if (!a || a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4)
      throw py::value_error("shadow map: a matrix must be (4, 4)");
    dmat4 m;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) m[c][r] = a.at(r, c);
    return m;
  };
  for (const py::handle& item : faces) {
    const py::tuple face = py::reinterpret_borrow<py::tuple>(item);
    if (face.size() != 4) throw py::value_error("shadow map: a face is (view, proj, orthographic, depth)");
    ShadowMapFace f;
    f.view = mat(face[0]);
    f.proj = mat(face[1]);
    f.orthographic = face[2].cast<bool>();
    auto depth = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(face[3]);
    if (!depth || depth.ndim() != 2 || depth.shape(0) != depth.shape(1) || depth.shape(0) < 1)
      throw py::value_error("shadow map: depth must be a square (n, n) array");
    f.size = int(depth.shape(0));
    f.depth.assign(depth.data(), depth.data() + depth.size());
    finish_face(f);
    map->faces.push_back(std::move(f));
  }
  light.shadow = ShadowMethod::Map;
  light.map = std::move(map);
}

void bind_draw(py::module_& m) {
  Record<DrawRecord>(m, "Draw", "One mesh instance: its mesh, pose, id, colour and material.")
      .field<std::shared_ptr<MeshData>>("mesh", "MeshData", "the geometry",
          +[](const DrawRecord& d) { return d.mesh; },
          +[](DrawRecord& d, std::shared_ptr<MeshData> v) { d.mesh = std::move(v); })
      .field<py::object>("pose", "numpy.ndarray", "model -> world, (4, 4) float64",
          +[](const DrawRecord& d) -> py::object { return matrix_to_array(d.pose); },
          +[](DrawRecord& d, py::object v) { d.pose = matrix_from_array(v, "Draw: pose"); })
      .field<int32_t>("instance_id", "int", "the instance_id output's value",
          +[](const DrawRecord& d) { return d.instance_id; },
          +[](DrawRecord& d, int32_t v) { d.instance_id = v; })
      .field<Rgba>("color", "tuple[float, float, float, float]",
          "linear RGBA: the base colour where the mesh has no vertex colours",
          +[](const DrawRecord& d) { return Rgba{d.color.r, d.color.g, d.color.b, d.color.a}; },
          +[](DrawRecord& d, Rgba v) { d.color = vec4(v[0], v[1], v[2], v[3]); })
      .field<py::object>("material", "Material | None", "None: Lambert of the base colour, two-sided",
          +[](const DrawRecord& d) -> py::object { return d.material ? py::cast(d.material) : py::none(); },
          +[](DrawRecord& d, py::object v) {
            if (!v.is_none() && !py::isinstance<MaterialRecord>(v))
              throw py::type_error("Draw: material must be a Material or None");
            d.material = v.is_none() ? nullptr : v.cast<std::shared_ptr<MaterialRecord>>();
          })
      .finish();
}

void bind_primitive(py::module_& m) {
  Record<PrimitiveRecord>(m, "Primitive",
                          "Lines or points (python/softrast/primitives.py), viewed: the record "
                          "keeps its arrays alive.")
      .field<bool>("points", "bool", "points (each position) rather than lines (segments)",
          +[](const PrimitiveRecord& p) { return p.draw.points; },
          +[](PrimitiveRecord& p, bool v) { p.draw.points = v; })
      .field<py::object>("positions", "numpy.ndarray", "(n, 3) float32, model space",
          +[](const PrimitiveRecord& p) { return p.positions; },
          +[](PrimitiveRecord& p, py::object v) {
            p.draw.positions = view_rows<float, vec3>(v, "Primitive: positions", 3);
            p.positions = v;
          })
      .field<py::object>("segments", "numpy.ndarray | None", "(m, 2) int32 endpoint indices (lines)",
          +[](const PrimitiveRecord& p) { return p.segments; },
          +[](PrimitiveRecord& p, py::object v) {
            p.draw.segments = v.is_none() ? ConstSpan<glm::ivec2>()
                                          : view_rows<int32_t, glm::ivec2>(v, "Primitive: segments", 2);
            p.segments = v;
          })
      .field<py::object>("colors", "numpy.ndarray | None", "(n, 3) float32 linear RGB per position",
          +[](const PrimitiveRecord& p) { return p.colors; },
          +[](PrimitiveRecord& p, py::object v) {
            p.draw.colors = v.is_none() ? ConstSpan<vec3>() : view_rows<float, vec3>(v, "Primitive: colors", 3);
            p.colors = v;
          })
      .field<Rgb>("color", "tuple[float, float, float]", "linear RGB without colors",
          +[](const PrimitiveRecord& p) { return rgb(p.draw.color); },
          +[](PrimitiveRecord& p, Rgb v) { p.draw.color = vec(v); })
      .field<float>("width", "float", "line width or point size, pixels",
          +[](const PrimitiveRecord& p) { return p.draw.width; },
          +[](PrimitiveRecord& p, float v) { p.draw.width = v; })
      .field<py::object>("pose", "numpy.ndarray", "model -> world, (4, 4) float64",
          +[](const PrimitiveRecord& p) -> py::object { return matrix_to_array(p.draw.model); },
          +[](PrimitiveRecord& p, py::object v) { p.draw.model = matrix_from_array(v, "Primitive: pose"); })
      .field<int32_t>("instance_id", "int", "the instance_id output's value",
          +[](const PrimitiveRecord& p) { return p.draw.instance_id; },
          +[](PrimitiveRecord& p, int32_t v) { p.draw.instance_id = v; })
      .field<float>("depth_bias", "float",
          "lines: nearer by this fraction of their depth in the depth test (wireframe)",
          +[](const PrimitiveRecord& p) { return p.draw.depth_bias; },
          +[](PrimitiveRecord& p, float v) { p.draw.depth_bias = v; })
      .finish();
}

}  // namespace

Draw DrawRecord::draw() const {
  Draw d;
  d.mesh = mesh;
  d.model = pose;
  d.instance_id = instance_id;
  d.color = color;
  if (material) {
    d.material = material->resolved();
    d.never_culled = d.material.double_sided;
  }
  return d;
}

Material MaterialRecord::resolved() const {
  Material m = material;
  if (m.emissive_texture) {  // the texture carries it, per pixel
    m.emissive_factor = emissive;
    m.emissive = vec3(0.0f);
  } else {
    m.emissive = emissive;
  }
  return m;
}

void bind_records(py::module_& m) {
  bind_material(m);
  bind_light(m);
  bind_draw(m);
  bind_primitive(m);
}

}  // namespace bind
}  // namespace sr
