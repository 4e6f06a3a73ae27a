// Python bindings: the module softrast._core. Its constants, the names of every option value
// (the one place each is spelled; Python checks a render's options against them), the output
// table, and the parts bound by topic (bind.hpp).
#include "bind.hpp"

#include "../framebuffer.hpp"
#include "../lines.hpp"
#include "../texture.hpp"
#include "../thread_pool.hpp"

namespace sr {
namespace bind {

const Name<Cull> kCullNames[3] = {{"none", Cull::None}, {"back", Cull::Back}, {"front", Cull::Front}};
const Name<Shading> kShadingNames[kNumShadings] = {
    {"auto", Shading::Auto},   {"unlit", Shading::Unlit}, {"lambert", Shading::Lambert},
    {"phong", Shading::Phong}, {"blinn_phong", Shading::BlinnPhong}, {"pbr", Shading::Pbr},
    {"normal", Shading::Normal}, {"uv", Shading::Uv}, {"depth", Shading::Depth}};
const Name<Brdf> kModelNames[kNumMaterialModels] = {{"unlit", Brdf::Unlit},           {"lambert", Brdf::Lambert},
                                   {"phong", Brdf::Phong},           {"blinn_phong", Brdf::BlinnPhong},
                                   {"pbr", Brdf::Pbr},               {"normal", Brdf::Normal}};
const Name<Frequency> kFrequencyNames[3] = {
    {"pixel", Frequency::Pixel}, {"vertex", Frequency::Vertex}, {"face", Frequency::Face}};
const Name<ShadingPath> kShadingPathNames[3] = {
    {"auto", ShadingPath::Auto}, {"forward", ShadingPath::Forward}, {"deferred", ShadingPath::Deferred}};
const Name<RasterAlgorithm> kRasterNames[2] = {{"edge", RasterAlgorithm::Edge},
                                               {"scanline", RasterAlgorithm::Scanline}};
const Name<int> kLineAlgorithmNames[2] = {{"bresenham", int(LineAlgorithm::Bresenham)},
                                          {"dda", int(LineAlgorithm::Dda)}};
const Name<int> kNormalKindNames[2] = {{"interpolated", 0}, {"shading", 1}};
const Name<int> kFilterNames[4] = {{"nearest", int(TextureFilter::Nearest)},
                                   {"bilinear", int(TextureFilter::Bilinear)},
                                   {"trilinear", int(TextureFilter::Trilinear)},
                                   {"anisotropic", int(TextureFilter::Anisotropic)}};
const Name<int> kWrapNames[3] = {{"repeat", int(Wrap::Repeat)}, {"clamp", int(Wrap::Clamp)},
                                 {"mirror", int(Wrap::Mirror)}};
const Name<LightKind> kLightKindNames[3] = {{"directional", LightKind::Directional},
                                            {"point", LightKind::Point},
                                            {"spot", LightKind::Spot}};
const Name<ShadowMethod> kShadowMethodNames[3] = {{"none", ShadowMethod::None},
                                                  {"exact", ShadowMethod::Exact},
                                                  {"map", ShadowMethod::Map}};

py::dict& record_docs() {
  static py::dict* docs = new py::dict();  // (made with the GIL held; lives as long as Python)
  return *docs;
}

}  // namespace bind
}  // namespace sr

PYBIND11_MODULE(_core, m) {
  using namespace sr;
  using namespace sr::bind;
  m.doc() = "softrast's C++ core (private: use the softrast package).";
  // Load NumPy's C API at import, as extension modules conventionally do: pybind11 otherwise
  // loads it on first use, in the first mesh upload.
  (void)py::dtype::of<float>();
  // Constants, each documented (the stub's comments, python/softrast/_stubgen.py).
  py::dict constants;
  const auto constant = [&](const char* name, py::object value, const char* doc) {
    m.attr(name) = value;
    constants[name] = doc;
  };
  constant("SUBPIXEL_BITS", py::int_(kSubpixelBits),
           "fixed-point precision of snapped window coordinates (8 => 1/256 px)");
  constant("TILE_SIZE_PX", py::int_(kTileSizePx), "side of the square screen tiles owned by one thread at a time");
  constant("MAX_IMAGE_SIDE", py::int_(kMaxImageSide), "largest width or height accepted");
  constant("MAX_FRAMEBUFFER_BYTES", py::int_(kMaxFramebufferBytes),
           "a render whose requested outputs need more than this is refused");
  constant("MAX_THREADS", py::int_(kMaxThreads), "largest thread count a Renderer accepts");
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
  constant("OUTPUTS", names, "every output name a render accepts, in the output table's order");
  constant("OUTPUT_TABLE", table,
           "one dict per output (cpp/framebuffer.hpp): name, dtype, channels (1 => (h, w), else "
           "(h, w, channels)), bytes_per_pixel, background, pass, doc");
  constant("SHADING_MODELS", names_of(kShadingNames),
           "render(shading=): 'auto' (each material's model) or one model for every draw");
  constant("REFLECTANCE_MODELS", names_of(kModelNames), "a material's models (Material.model)");
  constant("CULL_MODES", names_of(kCullNames), "cull=");
  constant("NORMAL_KINDS", names_of(kNormalKindNames), "normal_kind=");
  constant("SHADING_PATHS", names_of(kShadingPathNames), "shading_path=");
  constant("RASTER_ALGORITHMS", names_of(kRasterNames), "raster=");
  constant("LINE_ALGORITHMS", names_of(kLineAlgorithmNames), "line_algorithm=");
  constant("FREQUENCIES", names_of(kFrequencyNames), "frequency=");
  constant("TEXTURE_FILTERS", names_of(kFilterNames), "a texture's filter, or texture_filter=");
  constant("TEXTURE_WRAPS", names_of(kWrapNames), "a texture's wrap modes");
  constant("LIGHT_KINDS", names_of(kLightKindNames), "Light.kind");
  constant("SHADOW_METHODS", names_of(kShadowMethodNames), "Light.shadow");
  m.attr("CONSTANT_DOCS") = constants;

  bind_mesh(m);
  bind_texture(m);
  bind_records(m);
  bind_render(m);
  bind_distortion(m);
  bind_encode(m);
  bind_clip_raster(m);
  m.attr("RECORDS") = record_docs();
}
