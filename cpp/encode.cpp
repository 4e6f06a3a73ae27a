// PNG and TIFF files for datasets (encode.hpp): a PNG filter per row, then one deflate block of
// literals and runs coded with Huffman tables fitted to the image.
#include "encode.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <stdexcept>

#if defined(__SSE2__) && !defined(SR_ENCODE_SCALAR)
#include <emmintrin.h>
#endif

#define SR_ENC_INLINE inline __attribute__((always_inline))
// The PNG filters in 32-byte lanes where the machine has AVX2, chosen once at load time
// (integer code: the same bytes either way). Not under the sanitizers (ifuncs and ASan).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
#define SR_ENC_TARGET_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define SR_ENC_TARGET_CLONES
#endif

namespace sr {
namespace encode {
namespace {

// --- checksums ----------------------------------------------------------------------------------

// CRC-32 (PNG's: reflected polynomial 0xEDB88320), slicing by four.
struct CrcTables {
  uint32_t t[4][256];
  CrcTables() {
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[0][i] = c;
    }
    for (int s = 1; s < 4; ++s)
      for (uint32_t i = 0; i < 256; ++i) t[s][i] = (t[s - 1][i] >> 8) ^ t[0][t[s - 1][i] & 0xFF];
  }
};

const CrcTables& crc_tables() {
  static const CrcTables tables;
  return tables;
}

SR_ENC_INLINE uint32_t load_le32(const uint8_t* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

SR_ENC_INLINE void store_le32(uint8_t* p, uint32_t v) {
  p[0] = uint8_t(v);
  p[1] = uint8_t(v >> 8);
  p[2] = uint8_t(v >> 16);
  p[3] = uint8_t(v >> 24);
}

SR_ENC_INLINE void store_be32(uint8_t* p, uint32_t v) {
  p[0] = uint8_t(v >> 24);
  p[1] = uint8_t(v >> 16);
  p[2] = uint8_t(v >> 8);
  p[3] = uint8_t(v);
}

// A buffer of this thread's for scratch `Slot`, reused from call to call: a frame's scratch is
// then not fresh memory that the kernel maps and zeroes on every call (about 0.2 ms a MB, as
// much as encoding it). Shrunk when a call needs less than an eighth of it.
template <typename T, int Slot>
T* thread_scratch(std::size_t n) {
  thread_local std::vector<T> buffer;
  n = std::max<std::size_t>(n, 1);
  if (buffer.size() < n || buffer.size() / 8 > n) {
    buffer = std::vector<T>();
    buffer.resize(n);
  }
  return buffer.data();
}
enum ScratchSlot { kTokenSlot, kFilteredSlot, kStripSlot, kIdsSlot, kRowsSlot };

// --- deflate ------------------------------------------------------------------------------------

constexpr int kLitLenSymbols = 286;  // 0-255 literals, 256 end of block, 257-285 lengths
constexpr int kDistSymbols = 2;      // only distance 1 (code 0) is used; code 1 completes the code
constexpr int kMaxCodeBits = 15;
// Runs shorter than this are written as literals: a run of three or four equal bytes costs
// about as much as the literals in a table fitted to rendered images.
constexpr std::size_t kMinRun = 5;

// Length codes 257-285 (RFC 1951, 3.2.5): base length and extra bits.
constexpr uint16_t kLengthBase[29] = {3,  4,  5,  6,  7,  8,  9,  10, 11,  13,  15,  17,  19,  23, 27,
                                      31, 35, 43, 51, 59, 67, 83, 99, 115, 131, 163, 195, 227, 258};
constexpr uint8_t kLengthExtra[29] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2,
                                      2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0};

struct LengthCodes {
  uint8_t symbol[259];  // length 3..258 -> its code's index (0..28), i.e. symbol 257 + index
  LengthCodes() {
    for (int c = 0; c < 29; ++c) {
      const int end = c == 28 ? 259 : kLengthBase[c + 1];
      for (int l = kLengthBase[c]; l < end && l < 259; ++l) symbol[l] = uint8_t(c);
    }
    symbol[258] = 28;  // 258 has its own code (227 + 31 would also reach it with code 27)
  }
};

const LengthCodes& length_codes() {
  static const LengthCodes codes;
  return codes;
}

// The number of bytes from d[i] on that equal b (stopping at n).
SR_ENC_INLINE std::size_t run_length(const uint8_t* d, std::size_t i, std::size_t n, uint8_t b) {
  std::size_t j = i;
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  const uint64_t pattern = 0x0101010101010101ull * b;
  while (j + 8 <= n) {
    uint64_t v;
    std::memcpy(&v, d + j, 8);
    const uint64_t x = v ^ pattern;
    if (x) return j - i + std::size_t(__builtin_ctzll(x) >> 3);
    j += 8;
  }
#endif
  while (j < n && d[j] == b) ++j;
  return j - i;
}

// Tokens: 0-255 a literal byte, 256 + l a run of l (3..258) copies of the previous byte (a
// match at distance 1).
constexpr int kTokens = 256 + 259;

// The first i in [from, to) with d[i] == d[i - 1] (to if none); from >= 1. Eight bytes at a
// time: the lowest zero byte of d[i, i + 8) xor d[i - 1, i + 7) is found exactly (borrows
// only run upwards).
SR_ENC_INLINE std::size_t next_repeat(const uint8_t* d, std::size_t from, std::size_t to) {
  std::size_t i = from;
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  for (; i + 8 <= to; i += 8) {
    uint64_t v, w;
    std::memcpy(&v, d + i, 8);
    std::memcpy(&w, d + i - 1, 8);
    const uint64_t x = v ^ w;
    const uint64_t zero = (x - 0x0101010101010101ull) & ~x & 0x8080808080808080ull;
    if (zero) return i + std::size_t(__builtin_ctzll(zero) >> 3);
  }
#endif
  for (; i < to; ++i)
    if (d[i] == d[i - 1]) return i;
  return to;
}

// The tokens of d[0, n) into tok (n entries at most), counted by token: literals, and runs of
// the previous byte of kMinRun or more bytes, split into lengths of 3..258. prev is the byte
// before d[0] in the stream (-1 at its start): a run may continue across blocks. Returns the
// number of tokens.
std::size_t tokenize(const uint8_t* d, std::size_t n, int prev, uint16_t* tok, uint32_t* count) {
  if (n == 0) return 0;
  uint16_t* t = tok;
  std::size_t i = 0;
  for (;;) {
    std::size_t run = 0;
    uint8_t b = 0;
    if (i == 0) {
      if (prev >= 0 && d[0] == prev) {
        b = uint8_t(prev);
        run = run_length(d, 0, n, b);
      } else {
        ++count[d[0]];
        *t++ = d[0];
        i = 1;
        continue;
      }
    } else {
      const std::size_t j = next_repeat(d, i, n);
      for (; i < j; ++i) {  // literals up to the next repeated byte
        ++count[d[i]];
        *t++ = d[i];
      }
      if (i == n) break;
      b = d[i - 1];
      run = run_length(d, i, n, b);
    }
    i += run;
    if (run >= kMinRun) {
      while (run >= 3) {
        // 258 at a time, leaving at least 3 (or nothing) for the next match
        const std::size_t l = run <= 258 ? run : (run - 258 >= 3 ? 258 : run - 3);
        ++count[256 + l];
        *t++ = uint16_t(256 + l);
        run -= l;
      }
    }
    count[b] += uint32_t(run);
    for (; run; --run) *t++ = b;
    if (i == n) break;
  }
  return std::size_t(t - tok);
}

// Code lengths (at most max_bits) of a Huffman code for freq[0, n): symbols with frequency 0 get
// none, and at least two symbols get a code (a complete code: strict decoders refuse others).
// Deterministic: ties are broken by symbol; a code longer than max_bits is rebuilt from halved
// frequencies.
void huffman_lengths(const uint32_t* freq_in, int n, int max_bits, uint8_t* lengths) {
  std::vector<uint64_t> freq(freq_in, freq_in + n);
  int used = 0;
  for (int s = 0; s < n; ++s) used += freq[s] > 0;
  for (int s = 0; s < n && used < 2; ++s)
    if (freq[s] == 0) freq[s] = 1, ++used;
  std::vector<int> sym;
  std::vector<uint64_t> weight(2 * n);
  std::vector<int> parent(2 * n);
  for (;;) {
    sym.clear();
    for (int s = 0; s < n; ++s)
      if (freq[s]) sym.push_back(s);
    std::stable_sort(sym.begin(), sym.end(), [&](int a, int b) { return freq[a] < freq[b]; });
    const int m = int(sym.size());
    // leaves 0..m-1 (in sorted order), internal nodes m..2m-2 made in increasing weight
    for (int k = 0; k < m; ++k) weight[k] = freq[sym[k]];
    int leaf = 0, node = m, next = m;
    auto take = [&]() {
      if (leaf < m && (node >= next || weight[leaf] <= weight[node])) return leaf++;
      return node++;
    };
    for (; next < 2 * m - 1; ++next) {
      const int a = take(), b = take();
      weight[next] = weight[a] + weight[b];
      parent[a] = parent[b] = next;
    }
    // depths: the root (2m - 2) is 0; parents come after their children
    std::vector<int> depth(2 * m - 1, 0);
    int longest = 0;
    for (int k = 2 * m - 3; k >= 0; --k) {
      depth[k] = depth[parent[k]] + 1;
      if (k < m) longest = std::max(longest, depth[k]);
    }
    if (longest <= max_bits) {
      std::fill(lengths, lengths + n, uint8_t(0));
      for (int k = 0; k < m; ++k) lengths[sym[k]] = uint8_t(depth[k]);
      return;
    }
    for (int s = 0; s < n; ++s)
      if (freq[s]) freq[s] = (freq[s] >> 1) | 1;
  }
}

// Canonical codes (RFC 1951, 3.2.2), bit-reversed for deflate's least-significant-first stream.
void canonical_codes(const uint8_t* lengths, int n, uint16_t* codes) {
  int count[kMaxCodeBits + 1] = {};
  for (int s = 0; s < n; ++s) ++count[lengths[s]];
  count[0] = 0;
  int next[kMaxCodeBits + 2] = {};
  int code = 0;
  for (int bits = 1; bits <= kMaxCodeBits; ++bits) {
    code = (code + count[bits - 1]) << 1;
    next[bits] = code;
  }
  for (int s = 0; s < n; ++s) {
    const int len = lengths[s];
    if (!len) {
      codes[s] = 0;
      continue;
    }
    unsigned c = unsigned(next[len]++), r = 0;
    for (int k = 0; k < len; ++k, c >>= 1) r = (r << 1) | (c & 1);
    codes[s] = uint16_t(r);
  }
}

// Bits into a byte vector, least significant first, across blocks: put() stores four bytes at
// a time at out[at], so room for the block's bits and 8 bytes more is made first (reserve).
struct BitWriter {
  std::vector<uint8_t>& bytes;
  uint8_t* out = nullptr;
  uint64_t buffer = 0;
  int count = 0;
  BitWriter(std::vector<uint8_t>& b, uint64_t pending, int pending_count)
      : bytes(b), out(b.data() + b.size()), buffer(pending), count(pending_count) {}
  void reserve(uint64_t bits) {
    const std::size_t at = std::size_t(out - bytes.data());
    bytes.resize(at + std::size_t(bits / 8) + 16);
    out = bytes.data() + at;
  }
  // len <= 32
  SR_ENC_INLINE void put(uint32_t bits, int len) {
    buffer |= uint64_t(bits) << count;
    count += len;
    if (count >= 32) {
      store_le32(out, uint32_t(buffer));
      out += 4;
      buffer >>= 32;
      count -= 32;
    }
  }
  // to the next byte boundary (zero bits), written out (after reserve)
  void align() {
    for (; count > 0; count -= 8, buffer >>= 8) *out++ = uint8_t(buffer);
    count = 0;
    buffer = 0;
  }
  // the vector cut to the bytes written (the bits still in buffer are not)
  void close() { bytes.resize(std::size_t(out - bytes.data())); }
};

// The code-length sequence of the dynamic block header, run-length coded (symbols 16, 17, 18).
struct HeaderToken {
  uint8_t symbol, extra;
};

void header_tokens(const uint8_t* lens, int n, std::vector<HeaderToken>& out) {
  for (int i = 0; i < n;) {
    const uint8_t v = lens[i];
    int run = 1;
    while (i + run < n && lens[i + run] == v) ++run;
    i += run;
    if (v == 0) {
      while (run >= 11) {
        const int r = std::min(run, 138);
        out.push_back({18, uint8_t(r - 11)});
        run -= r;
      }
      if (run >= 3) {
        out.push_back({17, uint8_t(run - 3)});
        run = 0;
      }
    } else {
      out.push_back({v, 0});
      --run;
      while (run >= 3) {
        const int r = std::min(run, 6);
        out.push_back({16, uint8_t(r - 3)});
        run -= r;
      }
    }
    for (; run; --run) out.push_back({v, 0});
  }
}

constexpr uint8_t kCodeLengthOrder[19] = {16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15};
constexpr uint8_t kHeaderExtraBits[19] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 3, 7};

// Stored blocks of data[0, n) (at most 65535 bytes each), the last final if `last`.
void stored(const uint8_t* data, std::size_t n, bool last, BitWriter& w) {
  std::size_t i = 0;
  do {
    const std::size_t len = std::min<std::size_t>(n - i, 65535);
    w.reserve(3 + 7 + 32 + 8 * uint64_t(len));
    w.put(last && i + len == n ? 1 : 0, 3);  // BFINAL, BTYPE 00
    w.align();
    uint8_t* o = w.out;
    o[0] = uint8_t(len);
    o[1] = uint8_t(len >> 8);
    o[2] = uint8_t(~len);
    o[3] = uint8_t(~len >> 8);
    if (len) std::memcpy(o + 4, data + i, len);
    w.out = o + 4 + len;
    i += len;
  } while (i < n);
}

// --- PNG filters --------------------------------------------------------------------------------

// The Paeth residual of x with left a, up b and up-left c, in 16-bit lanes (vectorised).
SR_ENC_INLINE uint8_t paeth_residual(uint8_t x, uint8_t a8, uint8_t b8, uint8_t c8) {
  const int16_t a = a8, b = b8, c = c8;
  const int16_t d1 = int16_t(b - c), d2 = int16_t(a - c), d3 = int16_t(d1 + d2);
  const int16_t pa = d1 < 0 ? int16_t(-d1) : d1, pb = d2 < 0 ? int16_t(-d2) : d2,
                pc = d3 < 0 ? int16_t(-d3) : d3;
  const int16_t pred = (pa <= pb && pa <= pc) ? a : (pb <= pc ? b : c);
  return uint8_t(x - uint8_t(pred));
}

// |v| of a residual taken as a signed byte: min(v, -v) as unsigned bytes (vectorises).
SR_ENC_INLINE uint32_t magnitude(uint8_t v) {
  const uint8_t m = uint8_t(-v);
  return v < m ? v : m;
}

// Row `raw` (PNG byte order) filtered against `prev` (nullptr: the first row) into out[0] (the
// filter type) and out[1, 1 + n): the first row by Sub (1), the others by Up (2) or Paeth (4),
// whichever has the smaller sum of absolute residuals (ties to Up). Sub rarely wins on rendered
// images (flat backgrounds repeat down the image) and is not tried. `scratch` holds n bytes.
SR_ENC_TARGET_CLONES void filter_row(const uint8_t* raw, const uint8_t* prev, std::size_t n,
                                     std::size_t bpp, uint8_t* out, uint8_t* scratch) {
  uint8_t* row = out + 1;
  const std::size_t head = std::min(bpp, n);
  if (!prev) {
    out[0] = 1;
    for (std::size_t i = 0; i < head; ++i) row[i] = raw[i];
    for (std::size_t i = bpp; i < n; ++i) row[i] = uint8_t(raw[i] - raw[i - bpp]);
    return;
  }
  uint32_t cost_up = 0, cost_paeth = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const uint8_t u = uint8_t(raw[i] - prev[i]);
    row[i] = u;
    cost_up += magnitude(u);
  }
  if (cost_up == 0) {  // the row repeats the one above: nothing beats Up
    out[0] = 2;
    return;
  }
  for (std::size_t i = 0; i < head; ++i) {
    scratch[i] = row[i];  // Paeth's prediction is Up's in the first pixel
    cost_paeth += magnitude(row[i]);
  }
  for (std::size_t i = bpp; i < n; ++i) {
    const uint8_t p = paeth_residual(raw[i], raw[i - bpp], prev[i], prev[i - bpp]);
    scratch[i] = p;
    cost_paeth += magnitude(p);
  }
  if (cost_paeth < cost_up) {
    out[0] = 4;
    std::memcpy(row, scratch, n);
  } else {
    out[0] = 2;
  }
}

// Row r of the image in the file's sample order: 8-bit as is, wider samples big-endian.
const uint8_t* png_row(const Image& im, int r, uint8_t* swapped) {
  const uint8_t* src = im.pixels + std::ptrdiff_t(r) * im.row_stride;
  if (im.bytes_per_sample == 1) return src;
  const std::size_t n = im.row_bytes();
  for (std::size_t i = 0; i < n; i += 2) {
    swapped[i] = src[i + 1];
    swapped[i + 1] = src[i];
  }
  return swapped;
}

void put_chunk(std::vector<uint8_t>& out, const char* type, const uint8_t* data, std::size_t n) {
  uint8_t head[8];
  store_be32(head, uint32_t(n));
  std::memcpy(head + 4, type, 4);
  out.insert(out.end(), head, head + 8);
  out.insert(out.end(), data, data + n);
  uint32_t crc = crc32(head + 4, 4);
  crc = crc32(data, n, crc);
  uint8_t tail[4];
  store_be32(tail, crc);
  out.insert(out.end(), tail, tail + 4);
}

void check_image(const Image& im) {
  if (im.width < 1 || im.height < 1 || im.channels < 1 || im.channels > 4 || !im.pixels ||
      (im.bytes_per_sample != 1 && im.bytes_per_sample != 2 && im.bytes_per_sample != 4))
    throw std::invalid_argument("encode: bad image layout");
}

}  // namespace

uint32_t crc32(const uint8_t* p, std::size_t n, uint32_t crc) {
  const CrcTables& t = crc_tables();
  crc = ~crc;
  for (; n >= 4; n -= 4, p += 4) {
    crc ^= load_le32(p);
    crc = t.t[3][crc & 0xFF] ^ t.t[2][(crc >> 8) & 0xFF] ^ t.t[1][(crc >> 16) & 0xFF] ^ t.t[0][crc >> 24];
  }
  for (; n; --n, ++p) crc = t.t[0][(crc ^ *p) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

uint32_t adler32(const uint8_t* p, std::size_t n, uint32_t adler) {
  // Blocks of up to 5552 bytes (b stays below 2^32), 16 bytes at a time: a grows by the sum of
  // the 16 bytes, b by 16 a + the bytes weighted 16, 15, ..., 1.
  uint32_t a = adler & 0xFFFF, b = adler >> 16;
  while (n >= 16) {
    std::size_t blocks = std::min<std::size_t>(n / 16, 5552 / 16);
    n -= 16 * blocks;
#if defined(__SSE2__) && !defined(SR_ENCODE_SCALAR)
    // SSE2 (every x86-64): psadbw sums bytes, pmaddwd weights them; a's running sums are kept
    // in s1_sum and multiplied by 16 at the end of the block
    const __m128i zero = _mm_setzero_si128();
    const __m128i w_hi = _mm_setr_epi16(16, 15, 14, 13, 12, 11, 10, 9);
    const __m128i w_lo = _mm_setr_epi16(8, 7, 6, 5, 4, 3, 2, 1);
    __m128i s1 = _mm_cvtsi32_si128(int(a)), s2 = _mm_cvtsi32_si128(int(b));
    __m128i s1_sum = zero;
    for (; blocks; --blocks, p += 16) {
      const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
      s1_sum = _mm_add_epi32(s1_sum, s1);
      s1 = _mm_add_epi32(s1, _mm_sad_epu8(v, zero));
      s2 = _mm_add_epi32(s2, _mm_madd_epi16(_mm_unpacklo_epi8(v, zero), w_hi));
      s2 = _mm_add_epi32(s2, _mm_madd_epi16(_mm_unpackhi_epi8(v, zero), w_lo));
    }
    s2 = _mm_add_epi32(s2, _mm_slli_epi32(s1_sum, 4));
    uint32_t l1[4], l2[4];
    _mm_storeu_si128(reinterpret_cast<__m128i*>(l1), s1);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(l2), s2);
    a = (l1[0] + l1[2]) % 65521;  // psadbw's two sums are in lanes 0 and 2
    b = uint32_t((uint64_t(l2[0]) + l2[1] + l2[2] + l2[3]) % 65521);  // each lane < 2^32
#else
    uint64_t a64 = a, b64 = b;
    for (; blocks; --blocks, p += 16) {
      uint32_t sum = 0, weighted = 0;
      for (int i = 0; i < 16; ++i) {
        sum += p[i];
        weighted += uint32_t(16 - i) * p[i];
      }
      b64 += 16 * a64 + weighted;
      a64 += sum;
    }
    a = uint32_t(a64 % 65521);
    b = uint32_t(b64 % 65521);
#endif
  }
  for (; n; --n) {
    a += *p++;
    b += a;
  }
  return (b % 65521) << 16 | (a % 65521);
}

Deflater::Deflater(std::vector<uint8_t>& out) : out_(out) {
  out_.push_back(0x78);  // deflate, 32 KiB window
  out_.push_back(0x01);  // no dictionary, "fastest" (with the check bits: 0x7801 % 31 == 0)
}

void Deflater::block(const uint8_t* data, std::size_t n, bool last) {
  BitWriter w(out_, bit_buffer_, bit_count_);
  adler_ = adler32(data, n, adler_);
  // the tokens, counted, kept in a buffer of this thread's for the writing pass
  uint16_t* const token_buffer = thread_scratch<uint16_t, kTokenSlot>(n);
  uint32_t token_count[kTokens] = {};
  const std::size_t num_tokens = tokenize(data, n, prev_, token_buffer, token_count);
  if (n) prev_ = data[n - 1];
  uint32_t lit[kLitLenSymbols] = {};
  uint64_t extra_bits = 0;
  const LengthCodes& lc = length_codes();
  for (int b = 0; b < 256; ++b) lit[b] = token_count[b];
  for (int l = 3; l <= 258; ++l) {
    lit[257 + lc.symbol[l]] += token_count[256 + l];
    extra_bits += uint64_t(token_count[256 + l]) * kLengthExtra[lc.symbol[l]];
  }
  lit[256] = 1;  // end of block
  uint8_t lens[kLitLenSymbols + kDistSymbols];
  huffman_lengths(lit, kLitLenSymbols, kMaxCodeBits, lens);
  uint8_t* dist_lens = lens + kLitLenSymbols;
  dist_lens[0] = dist_lens[1] = 1;
  int hlit = kLitLenSymbols;
  while (hlit > 257 && lens[hlit - 1] == 0) --hlit;
  // the code-length sequence: literal/length lengths then distance lengths, as one sequence
  uint8_t seq[kLitLenSymbols + kDistSymbols];
  std::memcpy(seq, lens, std::size_t(hlit));
  std::memcpy(seq + hlit, dist_lens, kDistSymbols);
  std::vector<HeaderToken> tokens;
  header_tokens(seq, hlit + kDistSymbols, tokens);
  uint32_t cl_freq[19] = {};
  for (const HeaderToken& t : tokens) ++cl_freq[t.symbol];
  uint8_t cl_lens[19];
  huffman_lengths(cl_freq, 19, 7, cl_lens);
  uint16_t cl_codes[19];
  canonical_codes(cl_lens, 19, cl_codes);
  int hclen = 19;
  while (hclen > 4 && cl_lens[kCodeLengthOrder[hclen - 1]] == 0) --hclen;

  // the block's exact size in bits, to make room once (and to fall back to stored blocks)
  uint64_t bits = 3 + 5 + 5 + 4 + 3 * uint64_t(hclen) + extra_bits;
  for (const HeaderToken& t : tokens) bits += cl_lens[t.symbol] + kHeaderExtraBits[t.symbol];
  for (int s = 0; s < kLitLenSymbols; ++s) bits += uint64_t(lit[s]) * lens[s];
  for (int s = 257; s < kLitLenSymbols; ++s) bits += uint64_t(lit[s]) * dist_lens[0];
  const uint64_t stored_bits = 8 * (n + 5 * std::max<std::size_t>(1, (n + 65534) / 65535)) + 7;
  if (bits >= stored_bits) {
    stored(data, n, last, w);
    w.close();
    bit_buffer_ = w.buffer;
    bit_count_ = w.count;
    return;
  }
  uint16_t codes[kLitLenSymbols + kDistSymbols];
  canonical_codes(lens, kLitLenSymbols, codes);
  canonical_codes(dist_lens, kDistSymbols, codes + kLitLenSymbols);
  w.reserve(bits);
  w.put((last ? 1 : 0) | 2 << 1, 3);  // BFINAL, dynamic Huffman codes
  w.put(uint32_t(hlit - 257), 5);
  w.put(uint32_t(kDistSymbols - 1), 5);
  w.put(uint32_t(hclen - 4), 4);
  for (int k = 0; k < hclen; ++k) w.put(cl_lens[kCodeLengthOrder[k]], 3);
  for (const HeaderToken& t : tokens) {
    w.put(cl_codes[t.symbol], cl_lens[t.symbol]);
    if (kHeaderExtraBits[t.symbol]) w.put(t.extra, kHeaderExtraBits[t.symbol]);
  }
  // each token's bits in one put: a literal's code, or a length code with its extra bits and
  // the distance code (at most 15 + 5 + 1 bits)
  uint32_t token_code[kTokens] = {};
  uint8_t token_len[kTokens] = {};
  for (int b = 0; b < 256; ++b) {
    token_code[b] = codes[b];
    token_len[b] = lens[b];
  }
  for (int l = 3; l <= 258; ++l) {
    const int c = lc.symbol[l], sym = 257 + c;
    const int extra = kLengthExtra[c];
    uint32_t code = codes[sym] | uint32_t(l - kLengthBase[c]) << lens[sym];
    code |= uint32_t(codes[kLitLenSymbols]) << (lens[sym] + extra);  // distance 1
    token_code[256 + l] = code;
    token_len[256 + l] = uint8_t(lens[sym] + extra + dist_lens[0]);
  }
  const uint16_t* tok = token_buffer;
  for (std::size_t k = 0; k < num_tokens; ++k) w.put(token_code[tok[k]], token_len[tok[k]]);
  w.put(codes[256], lens[256]);
  w.close();
  bit_buffer_ = w.buffer;
  bit_count_ = w.count;
}

void Deflater::finish() {
  BitWriter w(out_, bit_buffer_, bit_count_);
  w.reserve(0);
  w.align();
  w.close();
  uint8_t tail[4];
  store_be32(tail, adler_);
  out_.insert(out_.end(), tail, tail + 4);
}

void zlib_compress(const uint8_t* data, std::size_t n, std::vector<uint8_t>& out) {
  Deflater z(out);
  std::size_t i = 0;
  do {
    const std::size_t len = std::min(n - i, kDeflateBlock);
    z.block(data + i, len, i + len == n);
    i += len;
  } while (i < n);
  z.finish();
}

std::vector<uint8_t> png(const Image& im) {
  check_image(im);
  if (im.bytes_per_sample > 2) throw std::invalid_argument("png: samples must be 8 or 16 bits");
  const std::size_t n = im.row_bytes(), bpp = std::size_t(im.channels) * im.bytes_per_sample;
  const std::size_t stride = n + 1;
  // rows filtered into a block of about kDeflateBlock bytes, deflated, and the next
  std::vector<uint8_t> z;
  z.reserve(stride * std::size_t(im.height) / 16 + 1024);
  Deflater deflater(z);
  const std::size_t rows_per_block = std::max<std::size_t>(1, kDeflateBlock / stride);
  uint8_t* const block = thread_scratch<uint8_t, kFilteredSlot>(rows_per_block * stride);
  uint8_t* const rows = thread_scratch<uint8_t, kRowsSlot>(3 * n);  // 2 swapped rows, Paeth's
  const uint8_t* prev = nullptr;
  std::size_t used = 0;
  for (int r = 0; r < im.height; ++r) {
    uint8_t* swapped = im.bytes_per_sample > 1 ? rows + (r & 1) * n : nullptr;
    const uint8_t* raw = png_row(im, r, swapped);
    filter_row(raw, prev, n, bpp, block + used, rows + 2 * n);
    prev = raw;
    used += stride;
    if (used == rows_per_block * stride || r + 1 == im.height) {
      deflater.block(block, used, r + 1 == im.height);
      used = 0;
    }
  }
  deflater.finish();
  std::vector<uint8_t> out = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  uint8_t ihdr[13];
  store_be32(ihdr, uint32_t(im.width));
  store_be32(ihdr + 4, uint32_t(im.height));
  ihdr[8] = uint8_t(8 * im.bytes_per_sample);
  static constexpr uint8_t kColourType[5] = {0, 0, 4, 2, 6};  // grey, grey + alpha, RGB, RGBA
  ihdr[9] = kColourType[im.channels];
  ihdr[10] = ihdr[11] = ihdr[12] = 0;  // deflate, adaptive filters, not interlaced
  put_chunk(out, "IHDR", ihdr, 13);
  constexpr std::size_t kMaxChunk = std::size_t(1) << 30;  // PNG chunks hold < 2^31 bytes
  out.reserve(out.size() + z.size() + 12 * (z.size() / kMaxChunk + 2));
  for (std::size_t i = 0; i < z.size() || i == 0; i += kMaxChunk)
    put_chunk(out, "IDAT", z.data() + i, std::min(kMaxChunk, z.size() - i));
  put_chunk(out, "IEND", nullptr, 0);
  return out;
}

std::vector<uint8_t> png_ids(const Image& ids) {
  check_image(ids);
  if (ids.channels != 1 || ids.bytes_per_sample != 4) throw std::invalid_argument("png_ids: ids must be int32");
  uint16_t* const plus_one = thread_scratch<uint16_t, kIdsSlot>(std::size_t(ids.width) * std::size_t(ids.height));
  uint32_t out_of_range = 0;
  for (int r = 0; r < ids.height; ++r) {
    const uint8_t* src = ids.pixels + std::ptrdiff_t(r) * ids.row_stride;
    uint16_t* dst = plus_one + std::size_t(r) * std::size_t(ids.width);
    for (int x = 0; x < ids.width; ++x) {
      int32_t v;
      std::memcpy(&v, src + 4 * std::size_t(x), 4);
      const uint32_t u = uint32_t(v) + 1u;  // -1..65534 -> 0..65535
      out_of_range |= u >> 16;
      dst[x] = uint16_t(u);
    }
  }
  if (out_of_range) throw std::out_of_range("png_ids: an id is outside -1..65534");
  Image im = ids;
  im.pixels = reinterpret_cast<const uint8_t*>(plus_one);
  im.bytes_per_sample = 2;
  im.row_stride = std::ptrdiff_t(2 * std::size_t(ids.width));
  return png(im);
}

std::vector<uint8_t> tiff(const Image& im, TiffSample sample, bool compress, TiffPredictor predictor) {
  check_image(im);
  const std::size_t n = im.row_bytes(), h = std::size_t(im.height);
  const int spp = im.channels, bps = im.bytes_per_sample;
  if (!compress) predictor = TiffPredictor::None;
  if (predictor == TiffPredictor::Float && sample != TiffSample::Float)
    throw std::invalid_argument("tiff: the floating-point predictor is for float samples");
  if (predictor == TiffPredictor::Horizontal && sample == TiffSample::Float)
    throw std::invalid_argument("tiff: the horizontal predictor is for integer samples");
  if (sample == TiffSample::Float && bps != 4) throw std::invalid_argument("tiff: float samples are 32-bit");

  // the strip: rows as stored (little-endian samples), after the predictor, in blocks of about
  // kDeflateBlock bytes, each deflated (or copied) before the next
  std::vector<uint8_t> out(8);
  if (compress) out.reserve(n * h / 16 + 1024);
  else out.reserve(8 + n * h + 256);
  std::optional<Deflater> deflater;
  if (compress) deflater.emplace(out);
  const std::size_t rows_per_block = std::max<std::size_t>(1, kDeflateBlock / n);
  uint8_t* const strip = thread_scratch<uint8_t, kStripSlot>(rows_per_block * n);  // all written
  std::size_t used = 0;
  for (std::size_t r = 0; r < h; ++r) {
    uint8_t* dst = strip + used;
    const uint8_t* src = im.pixels + std::ptrdiff_t(r) * im.row_stride;
    if (predictor == TiffPredictor::Float) {
      // byte planes, most significant first (libtiff's fpDiff), then differences of bytes
      // spp apart along the whole row
      const std::size_t wc = n / 4;
      for (std::size_t k = 0; k < wc; ++k)
        for (int b = 0; b < 4; ++b) dst[std::size_t(3 - b) * wc + k] = src[4 * k + std::size_t(b)];
      for (std::size_t i = n; i-- > std::size_t(spp);) dst[i] = uint8_t(dst[i] - dst[i - std::size_t(spp)]);
    } else if (predictor == TiffPredictor::Horizontal) {
      // differences of samples spp apart, modulo 2^bits, stored little-endian
      const std::size_t count = n / std::size_t(bps), step = std::size_t(spp);
      if (bps == 1) {
        for (std::size_t k = 0; k < count; ++k) dst[k] = uint8_t(src[k] - (k >= step ? src[k - step] : 0));
      } else if (bps == 2) {
        for (std::size_t k = 0; k < count; ++k) {
          uint16_t v, p = 0;
          std::memcpy(&v, src + 2 * k, 2);
          if (k >= step) std::memcpy(&p, src + 2 * (k - step), 2);
          const uint16_t d = uint16_t(v - p);
          dst[2 * k] = uint8_t(d);
          dst[2 * k + 1] = uint8_t(d >> 8);
        }
      } else {
        for (std::size_t k = 0; k < count; ++k) {
          uint32_t v = load_le32(src + 4 * k), p = k >= step ? load_le32(src + 4 * (k - step)) : 0;
          store_le32(dst + 4 * k, v - p);
        }
      }
    } else {
      std::memcpy(dst, src, n);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
      for (std::size_t i = 0; i < n; i += std::size_t(bps)) std::reverse(dst + i, dst + i + bps);
#endif
    }
    used += n;
    if (used == rows_per_block * n || r + 1 == h) {
      if (compress) deflater->block(strip, used, r + 1 == h);
      else out.insert(out.end(), strip, strip + used);
      used = 0;
    }
  }
  if (compress) deflater->finish();
  const std::size_t data_bytes = out.size() - 8;
  if (out.size() % 2) out.push_back(0);  // the IFD starts on a word boundary

  // the IFD, its entries in tag order; arrays of more than two shorts go after it
  struct Entry {
    uint16_t tag, type;
    uint32_t count, value;
  };
  constexpr uint16_t kShort = 3, kLong = 4;
  const bool rgb = spp >= 3;
  const int extra = spp - (rgb ? 3 : 1);
  std::vector<Entry> e;
  const std::size_t ifd_at = out.size();
  const int num_entries = 11 + (predictor != TiffPredictor::None) + (extra > 0);
  const std::size_t arrays_at = ifd_at + 2 + 12 * std::size_t(num_entries) + 4;
  std::vector<uint8_t> arrays;
  auto shorts = [&](uint16_t tag, int count, uint16_t v) {
    if (count <= 2) {
      e.push_back({tag, kShort, uint32_t(count), uint32_t(v) | (count == 2 ? uint32_t(v) << 16 : 0)});
    } else {
      e.push_back({tag, kShort, uint32_t(count), uint32_t(arrays_at + arrays.size())});
      for (int k = 0; k < count; ++k) {
        arrays.push_back(uint8_t(v));
        arrays.push_back(uint8_t(v >> 8));
      }
    }
  };
  e.push_back({256, kLong, 1, uint32_t(im.width)});
  e.push_back({257, kLong, 1, uint32_t(im.height)});
  shorts(258, spp, uint16_t(8 * bps));
  e.push_back({259, kShort, 1, compress ? 8u : 1u});  // Adobe deflate or none
  e.push_back({262, kShort, 1, rgb ? 2u : 1u});       // RGB or black is zero
  e.push_back({273, kLong, 1, 8});                    // the strip's offset
  e.push_back({277, kShort, 1, uint32_t(spp)});
  e.push_back({278, kLong, 1, uint32_t(im.height)});  // one strip
  e.push_back({279, kLong, 1, uint32_t(data_bytes)});
  e.push_back({284, kShort, 1, 1});  // chunky
  if (predictor != TiffPredictor::None) e.push_back({317, kShort, 1, uint32_t(predictor)});
  if (extra > 0) shorts(338, extra, rgb ? 2 : 0);  // unassociated alpha after RGB, else unspecified
  shorts(339, spp, uint16_t(sample));
  if (int(e.size()) != num_entries) throw std::logic_error("tiff: IFD size");
  if (arrays_at + arrays.size() > 0xFFFFFFFFull) throw std::length_error("tiff: over 4 GiB");
  out.resize(arrays_at);
  uint8_t* p = out.data() + ifd_at;
  p[0] = uint8_t(num_entries);
  p[1] = 0;
  p += 2;
  for (const Entry& x : e) {
    p[0] = uint8_t(x.tag);
    p[1] = uint8_t(x.tag >> 8);
    p[2] = uint8_t(x.type);
    p[3] = 0;
    store_le32(p + 4, x.count);
    if (x.type == kShort && x.count == 1) {
      p[8] = uint8_t(x.value);
      p[9] = uint8_t(x.value >> 8);
      p[10] = p[11] = 0;
    } else {
      store_le32(p + 8, x.value);
    }
    p += 12;
  }
  store_le32(p, 0);  // no next IFD
  if (!arrays.empty()) out.insert(out.end(), arrays.begin(), arrays.end());
  out[0] = 'I';
  out[1] = 'I';
  out[2] = 42;
  out[3] = 0;
  store_le32(out.data() + 4, uint32_t(ifd_at));
  return out;
}

}  // namespace encode
}  // namespace sr
