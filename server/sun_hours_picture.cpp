#include "sun_hours_picture.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <tuple>

namespace umbra {

namespace {

// ---------------------------------------------------------------------------
// Colours

using Rgb = std::array<unsigned char, 3>;

// Ladybug's "Original Ladybug" colour set, Colorset._colors[0] in
// ladybug/color.py (ladybug-tools/ladybug), which ColorRange uses when given
// no colours: the default of its legends, Direct Sun Hours' included.
// ColorRange spreads n colours evenly over the domain and blends linearly
// between neighbours, rounding each channel; hours_colour does the same.
constexpr Rgb kLadybugOriginal[] = {
    {75, 107, 169}, {115, 147, 202}, {170, 200, 247}, {193, 213, 208}, {245, 239, 103},
    {252, 230, 74}, {239, 156, 21},  {234, 123, 0},   {234, 74, 0},    {234, 38, 0},
};
constexpr int kColours = int(sizeof kLadybugOriginal / sizeof kLadybugOriginal[0]);

constexpr Rgb kBackground = {220, 220, 220};  // no geometry (NaN hours)
constexpr Rgb kPanel = {255, 255, 255};
constexpr Rgb kInk = {32, 32, 32};  // text, border, ticks, threshold mark

// ---------------------------------------------------------------------------
// The font: 5x7, one byte per row top to bottom, bit 4 the leftmost column.
// Drawn by hand for this file after the shapes of the classic 5x7
// dot-matrix character sets (the HD44780 LCD controller's ROM and the many
// public-domain 5x7 fonts that share its letterforms); no font file's
// bytes were copied.

struct Glyph {
  char32_t code;
  std::array<std::uint8_t, 7> rows;
};

// clang-format off
constexpr Glyph kFont[] = {
    {U'?', {0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b00000, 0b00100}},  // first: the fallback
    {U' ', {0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000}},
    {U'0', {0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110}},
    {U'1', {0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110}},
    {U'2', {0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111}},
    {U'3', {0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110}},
    {U'4', {0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010}},
    {U'5', {0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110}},
    {U'6', {0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110}},
    {U'7', {0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000}},
    {U'8', {0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110}},
    {U'9', {0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100}},
    {U'A', {0b01110, 0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001}},
    {U'B', {0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110}},
    {U'C', {0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110}},
    {U'D', {0b11100, 0b10010, 0b10001, 0b10001, 0b10001, 0b10010, 0b11100}},
    {U'E', {0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111}},
    {U'F', {0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000}},
    {U'G', {0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111}},
    {U'H', {0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001}},
    {U'I', {0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110}},
    {U'J', {0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100}},
    {U'K', {0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001}},
    {U'L', {0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111}},
    {U'M', {0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001}},
    {U'N', {0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001}},
    {U'O', {0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110}},
    {U'P', {0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000}},
    {U'Q', {0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101}},
    {U'R', {0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001}},
    {U'S', {0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110}},
    {U'T', {0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100}},
    {U'U', {0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110}},
    {U'V', {0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100}},
    {U'W', {0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010}},
    {U'X', {0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001}},
    {U'Y', {0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100}},
    {U'Z', {0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111}},
    {U'.', {0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b01100}},
    {U',', {0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b00100, 0b01000}},
    {U'-', {0b00000, 0b00000, 0b00000, 0b11111, 0b00000, 0b00000, 0b00000}},
    {U':', {0b00000, 0b01100, 0b01100, 0b00000, 0b01100, 0b01100, 0b00000}},
    {U'%', {0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011}},
    {U'/', {0b00000, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b00000}},
    {U'(', {0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010}},
    {U')', {0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000}},
    {U'>', {0b01000, 0b00100, 0b00010, 0b00001, 0b00010, 0b00100, 0b01000}},
    {U'<', {0b00010, 0b00100, 0b01000, 0b10000, 0b01000, 0b00100, 0b00010}},
    {U'=', {0b00000, 0b00000, 0b11111, 0b00000, 0b11111, 0b00000, 0b00000}},
    {U'+', {0b00000, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0b00000}},
    {U'_', {0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b11111}},
    {U'!', {0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00000, 0b00100}},
    {U'\'', {0b00100, 0b00100, 0b01000, 0b00000, 0b00000, 0b00000, 0b00000}},
    {U'\u00B0', {0b01100, 0b10010, 0b10010, 0b01100, 0b00000, 0b00000, 0b00000}},  // degree sign
};
// clang-format on

constexpr int kGlyphW = 5, kGlyphH = 7;

// UTF-8 to code points; a malformed byte becomes U+FFFD (drawn as '?').
std::u32string code_points(const std::string& text) {
  std::u32string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size();) {
    const unsigned char b = static_cast<unsigned char>(text[i]);
    int extra = b < 0x80 ? 0 : (b >> 5) == 0x6 ? 1 : (b >> 4) == 0xE ? 2 : (b >> 3) == 0x1E ? 3 : -1;
    char32_t cp = extra == 0 ? b : extra == 1 ? (b & 0x1F) : extra == 2 ? (b & 0x0F) : (b & 0x07);
    bool ok = extra >= 0 && i + std::size_t(std::max(extra, 0)) < text.size();
    for (int k = 1; ok && k <= extra; ++k) {
      const unsigned char c = static_cast<unsigned char>(text[i + std::size_t(k)]);
      if ((c >> 6) != 0x2) ok = false;
      cp = (cp << 6) | (c & 0x3F);
    }
    if (!ok) {
      out.push_back(U'\uFFFD');
      ++i;
      continue;
    }
    out.push_back(cp);
    i += std::size_t(extra) + 1;
  }
  return out;
}

// ---------------------------------------------------------------------------
// Drawing, clipped to the image.

void fill(Image& image, int x0, int y0, int w, int h, const Rgb& c) {
  const int x1 = std::min(image.width, x0 + w), y1 = std::min(image.height, y0 + h);
  for (int y = std::max(0, y0); y < y1; ++y)
    for (int x = std::max(0, x0); x < x1; ++x) std::copy(c.begin(), c.end(), image.row(y) + 3 * x);
}

// Text with its top-left corner at (x, y), each font dot an s x s square,
// 6 s per character.
void draw_text(Image& image, int x, int y, const std::u32string& text, int s, const Rgb& c) {
  for (char32_t cp : text) {
    const auto rows = legend_glyph(cp);
    for (int r = 0; r < kGlyphH; ++r)
      for (int col = 0; col < kGlyphW; ++col)
        if (rows[std::size_t(r)] & (0x10 >> col)) fill(image, x + col * s, y + r * s, s, s, c);
    x += (kGlyphW + 1) * s;
  }
}

// ---------------------------------------------------------------------------
// The legend's layout, in font units (one font dot; s pixels each).

constexpr int kAdvance = kGlyphW + 1;  // character advance
constexpr int kLineStep = kGlyphH + 2;  // line advance
constexpr int kPad = 4;                 // inside the panel's border
constexpr int kTitleGap = 4;            // title to the lines
constexpr int kSectionGap = 5;          // the text to the bar's labels
constexpr int kHalfLabel = 3;           // a label centred on a tick reaches 3 above and below
constexpr int kMarkW = 5;               // a threshold triangle (4 wide, 7 high) and its gap
constexpr int kBarW = 10;
constexpr int kTickLen = 3;
constexpr int kTickGap = 2;  // tick to label
constexpr int kColumnGap = 6;  // tick labels to the threshold's triangle and label
constexpr int kBarMin = 40, kBarMax = 100;
constexpr int kMinWidth = 200, kMinHeight = 120;  // smaller: colours only

int text_w(std::size_t chars) { return chars == 0 ? 0 : int(chars) * kAdvance - 1; }

std::string number(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%g", v);
  return buffer;
}

// Greedy wrap at spaces to at most `max_chars` (> 0) a line; a word longer
// than that is cut.
std::vector<std::u32string> wrap(const std::u32string& text, std::size_t max_chars) {
  std::vector<std::u32string> out;
  std::u32string line;
  std::size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && text[i] == U' ') ++i;
    std::size_t j = i;
    while (j < text.size() && text[j] != U' ') ++j;
    std::u32string word = text.substr(i, j - i);
    i = j;
    if (word.empty()) break;
    while (!word.empty()) {
      const std::size_t need = line.empty() ? word.size() : line.size() + 1 + word.size();
      if (need <= max_chars) {
        if (!line.empty()) line.push_back(U' ');
        line += word;
        word.clear();
      } else if (line.empty()) {  // a word longer than a line
        out.push_back(word.substr(0, max_chars));
        word.erase(0, max_chars);
      } else {
        out.push_back(line);
        line.clear();
      }
    }
  }
  if (!line.empty() || out.empty()) out.push_back(line);
  return out;
}

struct Layout {
  int s = 1;                          // pixels per font unit
  int left = 0, top = 0, w = 0, h = 0;  // the panel, pixels
  std::vector<std::u32string> lines;  // wrapped, those that fit
  int bar_top = 0, bar_h = 0;         // units from the panel's top
  std::vector<std::u32string> tick_labels;
  int label_w = 0;  // the widest tick label, units
};

std::optional<Layout> layout_at(int s, int width, int height, const SunHoursLegend& legend, const std::vector<double>& ticks,
                                const std::u32string& title, const std::u32string& require_label) {
  Layout l;
  l.s = s;
  const int margin = 3 * s;
  for (double t : ticks) {
    l.tick_labels.push_back(code_points(number(t)));
    l.label_w = std::max(l.label_w, text_w(l.tick_labels.back().size()));
  }
  const bool marked = !require_label.empty();
  const int bar_column = (marked ? kMarkW : 0) + kBarW + kTickLen + kTickGap + l.label_w +
                         (marked ? kColumnGap + kMarkW + 1 + text_w(require_label.size()) : 0);
  const int min_content = std::max(text_w(title.size()), bar_column);

  // Width: the title and the bar must fit; the lines wrap to half the image.
  const int room_w = (width - 2 * margin) / s;
  if (min_content + 2 * kPad > room_w) return std::nullopt;
  const int line_room = std::max(min_content, std::min(room_w, width / 2 / s) - 2 * kPad);
  const std::size_t max_chars = std::size_t((line_room + 1) / kAdvance);
  std::vector<std::u32string> wrapped;
  for (const std::string& line : legend.lines) {
    // Balanced: the narrowest wrap (cutting no word) with no more parts than
    // the widest has, so "... TO 2026-03-22T00:00 UTC" breaks after "TO",
    // not before "UTC".
    const std::u32string text = code_points(line);
    std::size_t longest_word = 0, run = 0;
    for (char32_t c : text) {
      run = c == U' ' ? 0 : run + 1;
      longest_word = std::max(longest_word, run);
    }
    std::vector<std::u32string> parts = wrap(text, max_chars);
    for (std::size_t m = max_chars - 1; parts.size() > 1 && m >= longest_word && m > 0; --m) {
      std::vector<std::u32string> narrower = wrap(text, m);
      if (narrower.size() > parts.size()) break;
      parts = std::move(narrower);
    }
    for (auto& part : parts) wrapped.push_back(std::move(part));
  }

  // Height: the title and a bar of its least height must fit; then as many
  // lines as fit; the bar takes what is left, up to its most.
  const int room_h = (height - 2 * margin) / s;
  const double step = ticks.size() > 1 ? ticks[1] - ticks[0] : legend.max_hours;
  const int bar_min = std::max(kBarMin, int(std::ceil(kLineStep * legend.max_hours / step)) + 1);
  const int fixed = kPad + kGlyphH + kSectionGap + 2 * kHalfLabel + kPad;
  if (fixed + bar_min > room_h) return std::nullopt;
  auto lines_h = [](std::size_t n) { return n == 0 ? 0 : kTitleGap + int(n) * kLineStep - (kLineStep - kGlyphH); };
  std::size_t n = wrapped.size();
  while (n > 0 && fixed + bar_min + lines_h(n) > room_h) --n;
  wrapped.resize(n);
  l.bar_h = std::min(kBarMax, room_h - fixed - lines_h(n));
  l.bar_top = kPad + kGlyphH + lines_h(n) + kSectionGap + kHalfLabel;

  int content = min_content;
  for (const auto& line : wrapped) content = std::max(content, text_w(line.size()));
  l.lines = std::move(wrapped);
  l.w = (content + 2 * kPad) * s;
  l.h = (l.bar_top + l.bar_h + kHalfLabel + kPad) * s;
  l.left = width - margin - l.w;
  l.top = margin;
  return l;
}

// A solid triangle 4 units wide and 7 high, its tip at column `tip` (the
// pixel column just past it when pointing right, its first when pointing
// left) and row `y`.
void triangle(Image& image, int tip, int y, int s, bool pointing_right) {
  for (int c = 0; c < kMarkW - 1; ++c) {  // c units from the tip, rows ±c
    const int x = pointing_right ? tip - (c + 1) * s : tip + c * s;
    fill(image, x, y - s / 2 - c * s, s, (2 * c + 1) * s, kInk);
  }
}

void draw_legend(Image& image, const SunHoursLegend& legend) {
  const double max_hours = legend.max_hours;
  const std::vector<double> ticks = sun_hours_ticks(max_hours);
  if (ticks.empty()) return;
  const std::u32string title = code_points("HOURS OF DIRECT SUN");
  const bool marked = std::isfinite(legend.require_hours);
  const std::u32string require_label = marked ? code_points(number(legend.require_hours) + " H REQUIRED") : U"";

  std::optional<Layout> found;
  for (int s = image.width >= 480 && image.height >= 240 ? 2 : 1; s >= 1 && !found; --s)
    found = layout_at(s, image.width, image.height, legend, ticks, title, require_label);
  if (!found) return;
  const Layout& l = *found;
  const int s = l.s;

  // The panel: white, a dark border one unit thick.
  fill(image, l.left, l.top, l.w, l.h, kInk);
  fill(image, l.left + s, l.top + s, l.w - 2 * s, l.h - 2 * s, kPanel);

  const int x0 = l.left + kPad * s;
  int y = l.top + kPad * s;
  draw_text(image, x0, y, title, s, kInk);
  y += (kGlyphH + kTitleGap) * s;
  for (const auto& line : l.lines) {
    draw_text(image, x0, y, line, s, kInk);
    y += kLineStep * s;
  }

  // The bar: max_hours at the top row, 0 at the bottom row.
  const int bar_x = x0 + (marked ? kMarkW : 0) * s, bar_w = kBarW * s;
  const int bar_y = l.top + l.bar_top * s, bar_h = l.bar_h * s;
  const int bottom = bar_y + bar_h - 1;
  for (int r = 0; r < bar_h; ++r) {
    Rgb c;
    hours_colour(max_hours * double(bar_h - 1 - r) / double(bar_h - 1), max_hours, c.data());
    fill(image, bar_x, bar_y + r, bar_w, 1, c);
  }
  auto y_of = [&](double hours) {
    return bottom - int(std::lround(std::clamp(hours / max_hours, 0.0, 1.0) * double(bar_h - 1)));
  };

  // Ticks and their labels, right of the bar.
  const int label_x = bar_x + bar_w + (kTickLen + kTickGap) * s;
  for (std::size_t i = 0; i < ticks.size(); ++i) {
    const int ty = y_of(ticks[i]);
    fill(image, bar_x + bar_w, ty - s / 2, kTickLen * s, s, kInk);
    draw_text(image, label_x, ty - kHalfLabel * s - s / 2, l.tick_labels[i], s, kInk);
  }

  // The threshold: a line across the bar, a triangle pointing at it from the
  // left, and its label, led by a triangle pointing back at the bar, in a
  // column of its own.
  if (marked) {
    const int ty = y_of(legend.require_hours);
    fill(image, bar_x - s, ty - s / 2, bar_w + 2 * s, s, kInk);
    triangle(image, bar_x - s, ty, s, true);  // its tip touches the line
    const int column = label_x + (l.label_w + kColumnGap) * s;
    triangle(image, column, ty, s, false);
    draw_text(image, column + (kMarkW + 1) * s, ty - kHalfLabel * s - s / 2, require_label, s, kInk);
  }
}

}  // namespace

void hours_colour(double hours, double max_hours, unsigned char rgb[3]) {
  double t = 0.0;
  if (!(max_hours > 0.0))
    t = hours > 0.0 ? 1.0 : 0.0;
  else if (hours > 0.0)  // NaN and below 0: 0
    t = std::min(hours / max_hours, 1.0);
  const double at = t * double(kColours - 1);
  const int i = std::min(int(at), kColours - 2);
  const double f = at - double(i);
  for (int k = 0; k < 3; ++k) {
    const double a = kLadybugOriginal[i][std::size_t(k)], b = kLadybugOriginal[i + 1][std::size_t(k)];
    rgb[k] = static_cast<unsigned char>(std::lround(a + f * (b - a)));
  }
}

std::vector<double> sun_hours_ticks(double max_hours) {
  if (!(max_hours > 0.0) || !std::isfinite(max_hours)) return {};
  // Mantissas by preference; 10^e from below the step that gives ~5 ticks.
  struct Mantissa {
    double m;
    int rank;
  };
  constexpr Mantissa kMantissas[] = {{1, 0}, {2, 0}, {5, 0}, {2.5, 1}, {4, 2}, {3, 3}};
  const int e0 = int(std::floor(std::log10(max_hours))) - 2;
  double best_step = 0.0, best_m = 1.0;
  int best_e = 0;
  std::tuple<int, int, double> best_score{1 << 30, 0, 0.0};
  for (int e = e0; e <= e0 + 3; ++e)
    for (const Mantissa& m : kMantissas) {
      const double step = m.m * std::pow(10.0, e);
      const double n = std::floor(max_hours / step + 1e-9);  // intervals
      const int tier = n >= 4 && n <= 6 ? 0 : n >= 3 && n <= 7 ? 1 : 2;
      const std::tuple<int, int, double> score{tier, m.rank, std::abs(n - 5.0)};
      if (score < best_score) best_score = score, best_step = step, best_m = m.m, best_e = e;
    }
  std::vector<double> ticks;
  const int n = int(std::floor(max_hours / best_step + 1e-9));
  // k * m * 10^e, dividing by 10^-e for a negative e so that 3 * 0.1 is 0.3.
  for (int k = 0; k <= n; ++k)
    ticks.push_back(best_e >= 0 ? double(k) * best_m * std::pow(10.0, best_e)
                                : double(k) * best_m / std::pow(10.0, -best_e));
  return ticks;
}

std::array<std::uint8_t, 7> legend_glyph(char32_t code_point) {
  if (code_point >= U'a' && code_point <= U'z') code_point -= U'a' - U'A';
  for (const Glyph& g : kFont)
    if (g.code == code_point) return g.rows;
  return kFont[0].rows;
}

Image sun_hours_picture(const std::vector<float>& hours, int width, int height, const SunHoursLegend& legend) {
  if (width <= 0 || height <= 0 || hours.size() != std::size_t(width) * std::size_t(height))
    throw std::invalid_argument("sun_hours_picture: hours must hold width * height values");
  Image image{width, height, 3, std::vector<std::uint8_t>(std::size_t(width) * std::size_t(height) * 3)};
  for (std::size_t i = 0; i < hours.size(); ++i) {
    unsigned char* p = image.pixels.data() + 3 * i;
    if (std::isnan(hours[i]))
      std::copy(kBackground.begin(), kBackground.end(), p);
    else
      hours_colour(hours[i], legend.max_hours, p);
  }
  if (width >= kMinWidth && height >= kMinHeight) draw_legend(image, legend);
  return image;
}

}  // namespace umbra
