// Bindings: textures. A texture's level 0 views the caller's array (kept alive by the Texture);
// python/softrast/texture.py checks and converts the image (uint8 as is, anything else to linear
// float32) and the options.
#include "bind.hpp"

#include "../texture.hpp"

namespace sr {
namespace bind {

using namespace pybind11::literals;

void bind_texture(py::module_& m) {
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

}

}  // namespace bind
}  // namespace sr
