// Bindings: image files for datasets (encode.hpp), encoded without the GIL, so that writer
// threads encode in parallel with each other and with renders. python/softrast/io.py checks the
// arrays and writes the files.
#include "bind.hpp"
#include "gil.hpp"

#include "../encode.hpp"

#include <stdexcept>
#include <utility>

namespace sr {
namespace bind {

using namespace pybind11::literals;

namespace {

// An (h, w) or (h, w, c) array whose pixels are contiguous within each row (rows may be apart).
encode::Image image_of(const py::array& a, const char* what) {
  if (a.ndim() != 2 && a.ndim() != 3) throw py::value_error(std::string(what) + ": array must be (h, w) or (h, w, c)");
  if (a.size() == 0) throw py::value_error(std::string(what) + ": array is empty");
  encode::Image im;
  im.height = int(a.shape(0));
  im.width = int(a.shape(1));
  im.channels = a.ndim() == 3 ? int(a.shape(2)) : 1;
  im.bytes_per_sample = int(a.itemsize());
  const py::ssize_t item = a.itemsize();
  const bool packed = (a.ndim() == 2 || a.strides(2) == item) && a.strides(1) == item * im.channels;
  if (!packed || a.strides(0) < 0 || a.shape(0) != py::ssize_t(im.height) || a.shape(1) != py::ssize_t(im.width))
    throw py::value_error(std::string(what) + ": each row's pixels must be contiguous");
  im.row_stride = a.strides(0);
  im.pixels = static_cast<const uint8_t*>(a.data());
  return im;
}

// f() with the GIL released; its result (or exception) handed back with the GIL held.
template <typename F>
std::vector<uint8_t> without_gil(F&& f) {
  PyThreadState* const saved = PyEval_SaveThread();
  std::vector<uint8_t> out;
  try {
    out = f();
  } catch (...) {
    take_gil_or_park(saved);
    throw;
  }
  take_gil_or_park(saved);
  return out;
}

py::bytes to_bytes(const std::vector<uint8_t>& v) {
  return py::bytes(reinterpret_cast<const char*>(v.data()), v.size());
}

}  // namespace

void bind_encode(py::module_& m) {
  m.def(
      "encode_png",
      [](const py::array& image) {
        const char kind = image.dtype().kind();
        if (kind != 'u' || (image.itemsize() != 1 && image.itemsize() != 2))
          throw py::type_error("encode_png: array must be uint8 or uint16");
        const encode::Image im = image_of(image, "encode_png");
        return to_bytes(without_gil([&] { return encode::png(im); }));
      },
      "image"_a,
      "PNG file bytes of a uint8 or uint16 (h, w) or (h, w, 1-4) array (any row stride): a "
      "filter per row, one deflate block of literals and runs. The GIL is released.");
  m.def(
      "encode_png_ids",
      [](const py::array_t<int32_t, 0>& ids) {
        const encode::Image im = image_of(ids, "encode_png_ids");
        try {
          return to_bytes(without_gil([&] { return encode::png_ids(im); }));
        } catch (const std::out_of_range&) {
          throw py::value_error("ids outside -1..65534 do not fit a 16-bit PNG (as id + 1)");
        }
      },
      "ids"_a,
      "16-bit grey PNG file bytes of (h, w) int32 ids stored as id + 1 (0 = background, -1); "
      "ValueError if an id is outside -1..65534. The GIL is released.");
  m.def(
      "encode_tiff",
      [](const py::array& image, int sample_format, bool compress, int predictor) {
        const encode::Image im = image_of(image, "encode_tiff");
        if (sample_format < 1 || sample_format > 3) throw py::value_error("encode_tiff: sample_format must be 1, 2 or 3");
        const char kind = image.dtype().kind(), want = "uif"[sample_format - 1];
        if (kind != want || (kind == 'f' && image.itemsize() != 4))
          throw py::type_error("encode_tiff: the array's dtype does not match sample_format (1: "
                               "unsigned, 2: signed, 3: float32)");
        if (predictor < 1 || predictor > 3) throw py::value_error("encode_tiff: predictor must be 1, 2 or 3");
        return to_bytes(without_gil([&] {
          return encode::tiff(im, encode::TiffSample(sample_format), compress, encode::TiffPredictor(predictor));
        }));
      },
      "image"_a, "sample_format"_a, "compress"_a, "predictor"_a,
      "TIFF file bytes of an (h, w) or (h, w, 1-4) array of 1-, 2- or 4-byte samples, one strip; "
      "sample_format 1 unsigned, 2 signed, 3 float; deflated after predictor (1 none, 2 "
      "horizontal, 3 floating point) when compress. The GIL is released.");
  m.def(
      "zlib_compress",
      [](const py::buffer& data) {
        const py::buffer_info info = data.request();
        if (!PyBuffer_IsContiguous(info.view(), 'C')) throw py::value_error("zlib_compress: the buffer must be C-contiguous");
        const auto* p = static_cast<const uint8_t*>(info.ptr);
        const std::size_t n = std::size_t(info.itemsize * info.size);
        return to_bytes(without_gil([&] {
          std::vector<uint8_t> out;
          encode::zlib_compress(p, n, out);
          return out;
        }));
      },
      "data"_a, "A zlib stream of a contiguous buffer (literals and runs; see encode_png).");
}

}  // namespace bind
}  // namespace sr
