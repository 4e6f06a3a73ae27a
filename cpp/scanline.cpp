// Scanline fill (scanline.hpp): each row's span by edge walking, then rasterize_large's depth test.
//
// The course notes' scanline fill sorts the vertices by y, then walks the edge from the top to
// the bottom vertex down one side and the two edges through the middle vertex down the other,
// filling between them row by row. Here the same walk is written with the setup's exact edge
// functions, so that it covers exactly the samples they cover. Along a row the biased edge
// function of edge k at pixel x0 + n is
//     c_k + s_k * n,   c_k = E_k(x0, y) - bias_k,  s_k = -dy_k * 256 (EdgeEquations::step_x)
// and the sample is covered iff that is >= 0 for every k (the top-left rule is in bias_k):
//     s_k > 0 (E grows to the right: a left edge)   n >= ceil(-c_k / s_k)
//     s_k < 0 (a right edge)                        n <= floor(c_k / -s_k)
//     s_k = 0 (a horizontal edge)                   every n if c_k >= 0, else none
// A triangle of positive area has one or two left edges and one or two right edges; the span
// starts at the largest left bound and ends at the smallest right bound: the left edge that
// binds is the one the notes' walk is on in that row (no split at the middle vertex is needed).
// A horizontal edge bounds rows instead (c_k changes only with y): it is where the walk starts
// or stops. From row to row c_k grows by dx_k * 256 (step_y), so each bound's numerator changes
// by a constant and the bound is stepped with an integer quotient and remainder (Bresenham's
// walk), one division per edge per tile. |c_k| < 2^51 and |s_k| < 2^33 (kGuardBandPx): every
// value fits in int64, exactly.
#include "scanline.hpp"

#include "rasterize.hpp"

#include <algorithm>

namespace sr {

namespace {

// floor(a / b) for b > 0 (C++ division truncates toward zero).
int64_t floor_div(int64_t a, int64_t b) {
  const int64_t q = a / b;
  return a % b < 0 ? q - 1 : q;
}

// The least integer j with a + b * j >= 0, for b > 0: ceil(-a / b).
int64_t first_inside(int64_t a, int64_t b) { return floor_div(b - 1 - a, b); }
// The largest integer j with a + b * j >= 0, for b < 0: floor(a / -b).
int64_t last_inside(int64_t a, int64_t b) { return floor_div(a, -b); }

// floor(num / m), m > 0, for a numerator that changes by `delta` from one row to the next,
// stepped as a quotient and a remainder in [0, m): additions only, exact.
struct EdgeWalk {
  int64_t q, r, m;  // num = q * m + r, 0 <= r < m; q is the bound
  int64_t dq, dr;   // delta = dq * m + dr, 0 <= dr < m
  EdgeWalk() = default;
  EdgeWalk(int64_t num, int64_t m_, int64_t delta) : m(m_) {
    q = floor_div(num, m);
    r = num - q * m;
    dq = floor_div(delta, m);
    dr = delta - dq * m;
  }
  void next_row() {
    q += dq;
    r += dr;
    if (r >= m) {  // the remainder carries into the quotient
      r -= m;
      ++q;
    }
  }
};

}  // namespace

bool rasterize_scanline(const TriangleSetup& t, int x0, int x1, int y0, int y1,
                        const TileRect& rect, uint32_t index, int32_t sample_x, int32_t sample_y,
                        bool coverage, TileScratch& s) {
  const EdgeEquations eq = edge_equations_at(t, x0, y0, sample_x, sample_y);
  // Rows: the box's, cut by horizontal edges (c_k + step_y_k * j >= 0 at row y0 + j).
  int64_t first = 0, last = y1 - y0;
  for (int k = 0; k < 3; ++k) {
    if (eq.step_x[k] != 0) continue;
    const int64_t c = eq.origin[k] - t.bias[k];
    if (eq.step_y[k] > 0) first = std::max(first, first_inside(c, eq.step_y[k]));  // a top edge
    else last = std::min(last, last_inside(c, eq.step_y[k]));                     // a bottom edge
  }
  if (first > last) return false;
  const int ya = y0 + int(first), yb = y0 + int(last);

  // The slanted edges at row ya: each bounds n = x - x0 from the left or from the right.
  int64_t c[3];
  EdgeWalk left[3], right[3];  // (one or two of each: a triangle of positive area)
  int num_left = 0, num_right = 0;
  for (int k = 0; k < 3; ++k) {
    c[k] = eq.origin[k] - t.bias[k] + eq.step_y[k] * (ya - y0);
    const int64_t sx = eq.step_x[k], sy = eq.step_y[k];
    if (sx > 0) left[num_left++] = EdgeWalk(sx - 1 - c[k], sx, -sy);  // n >= ceil(-c / sx)
    else if (sx < 0) right[num_right++] = EdgeWalk(c[k], -sx, sy);    // n <= floor(c / -sx)
  }

  const PixelDepthTest test(t, index);
  bool won = false;
  for (int y = ya; y <= yb; ++y) {
    int64_t lo = 0, hi = x1 - x0;  // the span, clipped to the box
    for (int j = 0; j < num_left; ++j) lo = std::max(lo, left[j].q);
    for (int j = 0; j < num_right; ++j) hi = std::min(hi, right[j].q);
    if (lo <= hi) {
      // The depth test as rasterize_large's (PixelDepthTest): the same exact edge values.
      int64_t e0 = c[0] + eq.step_x[0] * lo, e1 = c[1] + eq.step_x[1] * lo,
              e2 = c[2] + eq.step_x[2] * lo;
      const int line = (y - rect.y0) * kTileSizePx - rect.x0;
      for (int x = x0 + int(lo); x <= x0 + int(hi); ++x) {
        won |= test.run(line + x, e0, e1, e2, coverage, s);
        e0 += eq.step_x[0]; e1 += eq.step_x[1]; e2 += eq.step_x[2];
      }
    }
    for (int k = 0; k < 3; ++k) c[k] += eq.step_y[k];
    for (int j = 0; j < num_left; ++j) left[j].next_row();
    for (int j = 0; j < num_right; ++j) right[j].next_row();
  }
  return won;
}

}  // namespace sr
