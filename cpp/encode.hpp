// Image files for datasets: PNG and TIFF written fast, exactly and reproducibly
// (benchmarks/RESULTS.md, "Datasets and encoders").
//
// A render's frame is encoded in the time it takes to read it a few times: the general encoders
// (libpng, zlib level 1) spend 10-16 ms on a 640x480 colour frame choosing matches and filters,
// and hold the GIL doing it. Rendered images are flat backgrounds and smooth shading, which a
// PNG filter turns into long runs of equal bytes: so the deflate stream here is one dynamic
// Huffman block of literals and runs (matches at distance 1), fpnge's approach, in three linear
// passes (filter, count, write). Every step is integer code with no dependence on the machine:
// the same image gives the same bytes on every machine, thread count and instruction set.
// Standard files: any PNG or TIFF reader opens them (zlib's inflate decodes the stream).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace sr {
namespace encode {

// An image of `height` rows of `width` pixels of `channels` samples, each `bytes_per_sample`
// (1, 2 or 4) bytes in the machine's order; row r starts at pixels + r * row_stride bytes.
struct Image {
  const uint8_t* pixels = nullptr;
  int width = 0, height = 0, channels = 0, bytes_per_sample = 1;
  std::ptrdiff_t row_stride = 0;
  std::size_t row_bytes() const { return std::size_t(width) * channels * bytes_per_sample; }
};

// A zlib stream (RFC 1950) appended to `out`, given in pieces: each piece is a deflate block of
// literals and runs (matches at distance 1, a run continuing across pieces) with Huffman codes
// fitted to it, or stored blocks when that is smaller. Pieces of about kDeflateBlock bytes keep
// a block's data and tokens in the core's cache; each costs a code table (~50-100 bytes).
class Deflater {
 public:
  explicit Deflater(std::vector<uint8_t>& out);
  void block(const uint8_t* data, std::size_t n, bool last);  // `last`: the final block
  void finish();  // after the last block: the checksum
 private:
  std::vector<uint8_t>& out_;
  uint64_t bit_buffer_ = 0;  // bits not yet written to out_
  int bit_count_ = 0;
  uint32_t adler_ = 1;
  int prev_ = -1;  // the last byte given, -1 before any
};
constexpr std::size_t kDeflateBlock = 2 * 65535;  // (stored blocks hold 65535 bytes at most)

// The zlib stream of data[0, n), in blocks of kDeflateBlock bytes.
void zlib_compress(const uint8_t* data, std::size_t n, std::vector<uint8_t>& out);

// A PNG file of an 8- or 16-bit image (1: grey, 2: grey + alpha, 3: RGB, 4: RGBA); 16-bit
// samples are written big-endian, as PNG stores them. The first row is filtered by Sub, each
// other by Up or Paeth, whichever has the smaller sum of absolute residuals.
std::vector<uint8_t> png(const Image& image);

// A 16-bit grey PNG of int32 ids stored as id + 1 (0: background, -1); std::out_of_range if an
// id is outside -1..65534 (nothing is written).
std::vector<uint8_t> png_ids(const Image& ids);

// Sample formats of a TIFF (its SampleFormat tag).
enum class TiffSample { Unsigned = 1, Signed = 2, Float = 3 };

// TIFF predictors (the Predictor tag): none, horizontal differencing (integer samples), or the
// floating-point one (float samples: byte planes, then differencing).
enum class TiffPredictor { None = 1, Horizontal = 2, Float = 3 };

// A little-endian baseline TIFF of the image in one strip, deflated (Adobe deflate) after
// `predictor` when `compress`, else stored as is (and the predictor is None). Channels 3 are
// RGB, the others grey with extra samples.
std::vector<uint8_t> tiff(const Image& image, TiffSample sample, bool compress,
                          TiffPredictor predictor);

uint32_t crc32(const uint8_t* data, std::size_t n, uint32_t crc = 0);
uint32_t adler32(const uint8_t* data, std::size_t n, uint32_t adler = 1);

}  // namespace encode
}  // namespace sr
