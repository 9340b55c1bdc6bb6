#include "stereo_ground_dem/io/DemPicture.hpp"

#include "stereo_ground_dem/GreyConverter.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

namespace stereo_ground_dem {

namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kFontScale = 0.5;
constexpr double kTitleScale = 0.7;
constexpr int kMargin = 16;
const cv::Scalar kInk(25, 25, 25);
const cv::Scalar kPaper(245, 245, 245);

/// The smallest of 1, 2, 5 x 10^k that is >= raw.
double niceCeil(double raw) {
  if (!(raw > 0.0) || !std::isfinite(raw)) return 1.0;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / p;
  return (f <= 1.0 + 1e-9 ? 1.0 : f <= 2.0 + 1e-9 ? 2.0 : f <= 5.0 + 1e-9 ? 5.0 : 10.0) * p;
}

/// The largest of 1, 2, 5 x 10^k that is <= raw.
double niceFloor(double raw) {
  if (!(raw > 0.0) || !std::isfinite(raw)) return 1.0;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / p;
  return (f >= 5.0 - 1e-9 ? 5.0 : f >= 2.0 - 1e-9 ? 2.0 : 1.0) * p;
}

int decimalsFor(double step) { return std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9))); }

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  std::string s = buf;
  if (s[0] == '-' && s.find_first_not_of("-0.") == std::string::npos) s.erase(0, 1);  // no "-0.0"
  return s;
}

cv::Size textSize(const std::string& s, double scale = kFontScale, int thickness = 1) {
  int baseline = 0;
  return cv::getTextSize(s, kFont, scale, thickness, &baseline);
}

void text(cv::Mat& img, const std::string& s, cv::Point org, double scale = kFontScale, int thickness = 1,
          const cv::Scalar& colour = kInk) {
  cv::putText(img, s, org, kFont, scale, colour, thickness, cv::LINE_AA);
}

cv::Vec3b lutAt(const cv::Mat& lut, double u) {
  const double c = std::min(1.0, std::max(0.0, u));
  return lut.at<cv::Vec3b>(0, static_cast<int>(std::lround(c * 255.0)));
}

struct Ticks {
  std::vector<double> values;
  int decimals = 0;
};

Ticks ticksFor(double lo, double hi) {
  Ticks t;
  const double step = niceCeil((hi - lo) / 5.0);
  t.decimals = decimalsFor(step);
  for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step) t.values.push_back(v);
  return t;
}

/// Vertical colour bar, high values on top, ticks and labels on its right.
void drawVerticalBar(cv::Mat& canvas, const cv::Rect& bar, const cv::Mat& lut, double lo, double hi,
                     const std::string& unit, const Ticks& ticks) {
  for (int y = 0; y < bar.height; ++y) {
    const cv::Vec3b c = lutAt(lut, 1.0 - (y + 0.5) / bar.height);
    cv::line(canvas, {bar.x, bar.y + y}, {bar.x + bar.width - 1, bar.y + y}, cv::Scalar(c[0], c[1], c[2]));
  }
  cv::rectangle(canvas, bar, kInk, 1);
  for (double v : ticks.values) {
    const int y = bar.y + static_cast<int>(std::lround((1.0 - (v - lo) / (hi - lo)) * (bar.height - 1)));
    cv::line(canvas, {bar.x + bar.width, y}, {bar.x + bar.width + 5, y}, kInk, 1);
    text(canvas, fixed(v, ticks.decimals) + unit, {bar.x + bar.width + 9, y + 5});
  }
}

/// Horizontal colour bar, high values on the right, labels below.
void drawHorizontalBar(cv::Mat& canvas, const cv::Rect& bar, const cv::Mat& lut, double lo, double hi,
                       const Ticks& ticks) {
  for (int x = 0; x < bar.width; ++x) {
    const cv::Vec3b c = lutAt(lut, (x + 0.5) / bar.width);
    cv::line(canvas, {bar.x + x, bar.y}, {bar.x + x, bar.y + bar.height - 1}, cv::Scalar(c[0], c[1], c[2]));
  }
  cv::rectangle(canvas, bar, kInk, 1);
  for (double v : ticks.values) {
    const int x = bar.x + static_cast<int>(std::lround((v - lo) / (hi - lo) * (bar.width - 1)));
    cv::line(canvas, {x, bar.y + bar.height}, {x, bar.y + bar.height + 4}, kInk, 1);
    const std::string s = fixed(v, ticks.decimals);
    text(canvas, s, {x - textSize(s).width / 2, bar.y + bar.height + 18});
  }
}

/// Scale bar of a nice length of at most max_px pixels, left end at `left` (its baseline).
void drawScaleBar(cv::Mat& canvas, cv::Point left, double metres_per_px, int max_px) {
  const double len_m = niceFloor(max_px * metres_per_px);
  const int len_px = std::max(1, static_cast<int>(std::lround(len_m / metres_per_px)));
  const cv::Point right(left.x + len_px, left.y);
  cv::rectangle(canvas, cv::Rect(left.x, left.y - 6, len_px, 6), kInk, cv::FILLED);
  cv::rectangle(canvas, cv::Rect(left.x + len_px / 2, left.y - 6, len_px - len_px / 2, 6), kPaper,
                cv::FILLED);
  cv::rectangle(canvas, cv::Rect(left.x, left.y - 6, len_px, 6), kInk, 1);
  text(canvas, "0", {left.x - 4, left.y - 12});
  const std::string label = fixed(len_m, decimalsFor(len_m)) + " m";
  text(canvas, label, {right.x - textSize(label).width / 2, left.y - 12});
}

/// The "x up, y left" sign, corner at `origin`.
void drawAxes(cv::Mat& canvas, cv::Point origin, int len) {
  cv::arrowedLine(canvas, origin, {origin.x, origin.y - len}, kInk, 2, cv::LINE_AA, 0, 0.25);
  cv::arrowedLine(canvas, origin, {origin.x - len, origin.y}, kInk, 2, cv::LINE_AA, 0, 0.25);
  text(canvas, "x forward", {origin.x - 18, origin.y - len - 8});
  text(canvas, "y left", {origin.x - len - 8, origin.y + 20});
}

void drawTrajectory(cv::Mat& canvas, const DemPictureLayout& layout,
                    const std::vector<Eigen::Vector2d>& trajectory_xy_m) {
  if (trajectory_xy_m.empty()) return;
  cv::Mat map = canvas(layout.map_rect);
  constexpr int kShift = 4;  // sub-pixel drawing: coordinates in 1/16 px
  std::vector<cv::Point> pts;
  for (const Eigen::Vector2d& p : trajectory_xy_m) {
    const cv::Point2d q = layout.pixelOf(p.x(), p.y()) - cv::Point2d(layout.map_rect.tl());
    pts.emplace_back(static_cast<int>(std::lround(q.x * (1 << kShift))),
                     static_cast<int>(std::lround(q.y * (1 << kShift))));
  }
  if (pts.size() > 1) {
    cv::polylines(map, pts, false, cv::Scalar(0, 0, 0), 5, cv::LINE_AA, kShift);
    cv::polylines(map, pts, false, cv::Scalar(255, 255, 255), 2, cv::LINE_AA, kShift);
    cv::circle(map, pts.back(), 4 << kShift, cv::Scalar(255, 255, 255), cv::FILLED, cv::LINE_AA, kShift);
    cv::circle(map, pts.back(), 4 << kShift, cv::Scalar(0, 0, 0), 1, cv::LINE_AA, kShift);
  }
  cv::circle(map, pts.front(), 7 << kShift, cv::Scalar(60, 200, 60), cv::FILLED, cv::LINE_AA, kShift);
  cv::circle(map, pts.front(), 7 << kShift, cv::Scalar(0, 0, 0), 2, cv::LINE_AA, kShift);
  const cv::Point s(pts.front().x >> kShift, pts.front().y >> kShift);
  text(map, "start", {s.x + 10, s.y + 18}, kFontScale, 3, cv::Scalar(0, 0, 0));
  text(map, "start", {s.x + 10, s.y + 18}, kFontScale, 1, cv::Scalar(255, 255, 255));
}

/// The cells of `grid` oriented for the picture: picture row i = grid column cols-1-i (x up),
/// picture column j = grid row rows-1-j (y left).
template <typename F>
cv::Mat orientedCells(const GroundGrid& grid, F colour_of) {
  cv::Mat cells(grid.cols, grid.rows, CV_8UC3);
  for (int i = 0; i < grid.cols; ++i) {
    cv::Vec3b* row = cells.ptr<cv::Vec3b>(i);
    for (int j = 0; j < grid.rows; ++j) row[j] = colour_of(grid.rows - 1 - j, grid.cols - 1 - i);
  }
  return cells;
}

double pixelsPerCell(const GroundGrid& grid, const DemPictureOptions& o) {
  if (o.pixels_per_cell > 0.0) return o.pixels_per_cell;
  const double f = static_cast<double>(o.auto_map_size_px) / std::max(grid.rows, grid.cols);
  return f >= 1.0 ? std::round(f) : f;
}

void checkInputs(const char* who, const cv::Mat& layer, const GroundGrid& grid, const DemPictureOptions& o) {
  std::string why;
  if (!o.isValid(&why)) throw std::invalid_argument(std::string(who) + ": invalid options: " + why);
  if (grid.rows <= 0 || grid.cols <= 0 || !(grid.resolution_m > 0.0)) {
    throw std::invalid_argument(std::string(who) + ": empty or invalid grid");
  }
  if (layer.type() != CV_32FC1 || layer.rows != grid.rows || layer.cols != grid.cols) {
    throw std::invalid_argument(std::string(who) + ": layer is not CV_32F of grid.rows x grid.cols");
  }
}

/// Lays out title, map, legend (vertical bar + unknown swatch + axes sign) and scale bar.
cv::Mat composeMap(const cv::Mat& cells, const GroundGrid& grid, const DemPictureOptions& o,
                   const std::string& title, const std::string& legend_title, const cv::Mat& lut, double lo,
                   double hi, const std::string& unit, const std::vector<Eigen::Vector2d>& trajectory_xy_m,
                   DemPictureLayout* layout_out) {
  const double ppc = pixelsPerCell(grid, o);
  const int map_w = std::max(1, static_cast<int>(std::lround(grid.rows * ppc)));
  const int map_h = std::max(1, static_cast<int>(std::lround(grid.cols * ppc)));
  cv::Mat map;
  cv::resize(cells, map, cv::Size(map_w, map_h), 0, 0, ppc >= 1.0 ? cv::INTER_NEAREST : cv::INTER_AREA);

  const Ticks ticks = ticksFor(lo, hi);
  int label_w = textSize("unknown").width;
  for (double v : ticks.values) label_w = std::max(label_w, textSize(fixed(v, ticks.decimals) + unit).width);
  const int bar_w = 20;
  const int panel_w = std::max({textSize(legend_title).width, bar_w + 9 + label_w, 150});
  const int title_h = 44;
  const int map_x = kMargin, map_y = kMargin + title_h;
  const int panel_x = map_x + map_w + 30;
  const int bar_h = std::max(160, std::min(400, map_h - 140));
  const cv::Rect bar(panel_x, map_y + 28, bar_w, bar_h);
  const cv::Rect swatch(panel_x, bar.br().y + 20, bar_w, 14);
  const cv::Point axes(panel_x + 80, swatch.br().y + 80);
  const int bottom = std::max(map_y + map_h, axes.y + 24) + 52;
  const int width =
      std::max(panel_x + panel_w + kMargin, textSize(title, kTitleScale, 2).width + 2 * kMargin);
  cv::Mat canvas(bottom, width, CV_8UC3, kPaper);

  text(canvas, title, {kMargin, kMargin + 22}, kTitleScale, 2);
  map.copyTo(canvas(cv::Rect(map_x, map_y, map_w, map_h)));
  cv::rectangle(canvas, cv::Rect(map_x - 1, map_y - 1, map_w + 2, map_h + 2), kInk, 1);
  text(canvas, legend_title, {panel_x, bar.y - 12});
  drawVerticalBar(canvas, bar, lut, lo, hi, unit, ticks);
  cv::rectangle(canvas, swatch, cv::Scalar(o.unknown_bgr[0], o.unknown_bgr[1], o.unknown_bgr[2]), cv::FILLED);
  cv::rectangle(canvas, swatch, kInk, 1);
  text(canvas, "unknown", {swatch.br().x + 9, swatch.br().y - 2});
  drawAxes(canvas, axes, 44);
  const double metres_per_px = grid.resolution_m / ppc;
  drawScaleBar(canvas, {map_x + 6, map_y + map_h + 36}, metres_per_px, std::max(20, map_w / 3));

  DemPictureLayout layout;
  layout.map_rect = cv::Rect(map_x, map_y, map_w, map_h);
  layout.pixels_per_cell = ppc;
  layout.grid = grid;
  drawTrajectory(canvas, layout, trajectory_xy_m);
  if (layout_out != nullptr) *layout_out = layout;
  return canvas;
}

std::string resolutionText(const GroundGrid& grid) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", grid.resolution_m);
  return std::string(buf) + " m grid";
}

}  // namespace

bool DemPictureOptions::isValid(std::string* why) const {
  const auto bad = [why](const char* reason) {
    if (why != nullptr) *why = reason;
    return false;
  };
  if (!std::isfinite(pixels_per_cell)) return bad("pixels_per_cell must be finite");
  if (auto_map_size_px < 16 || auto_map_size_px > 20000)
    return bad("auto_map_size_px must be in [16, 20000]");
  if (!(low_percentile >= 0.0 && low_percentile < high_percentile && high_percentile <= 100.0)) {
    return bad("need 0 <= low_percentile < high_percentile <= 100");
  }
  if (!std::isnan(min_value) && !std::isnan(max_value) && !(min_value < max_value)) {
    return bad("min_value must be below max_value");
  }
  if (height_colormap < 0 || height_colormap > cv::COLORMAP_DEEPGREEN || overlay_colormap < 0 ||
      overlay_colormap > cv::COLORMAP_DEEPGREEN) {
    return bad("colormaps must be OpenCV COLORMAP_* values");
  }
  if (!(hillshade_strength >= 0.0 && hillshade_strength <= 1.0))
    return bad("hillshade_strength must be in [0, 1]");
  if (!(hillshade_z_factor > 0.0)) return bad("hillshade_z_factor must be > 0");
  if (!(light_elevation_deg > 0.0 && light_elevation_deg <= 90.0))
    return bad("light_elevation_deg must be in (0, 90]");
  if (!std::isfinite(light_azimuth_deg)) return bad("light_azimuth_deg must be finite");
  if (!(overlay_alpha >= 0.0 && overlay_alpha <= 1.0)) return bad("overlay_alpha must be in [0, 1]");
  if (image_bit_depth != 0 && (image_bit_depth < 8 || image_bit_depth > 16)) {
    return bad("image_bit_depth must be 0 (detect) or 8..16");
  }
  return true;
}

cv::Point2d DemPictureLayout::pixelOf(double x_m, double y_m) const {
  const double col_f = (x_m - grid.x0()) / grid.resolution_m;  // grid column (x)
  const double row_f = (y_m - grid.y0()) / grid.resolution_m;  // grid row (y)
  return {map_rect.x + (grid.rows - 1 - row_f + 0.5) * pixels_per_cell,
          map_rect.y + (grid.cols - 1 - col_f + 0.5) * pixels_per_cell};
}

bool DemPicture::robustRange(const cv::Mat& layer, double low_pct, double high_pct, double* lo, double* hi,
                             bool zero_is_none) {
  if (layer.type() != CV_32FC1) throw std::invalid_argument("DemPicture::robustRange: layer is not CV_32F");
  std::vector<float> v;
  v.reserve(layer.total());
  for (int r = 0; r < layer.rows; ++r) {
    const float* p = layer.ptr<float>(r);
    for (int c = 0; c < layer.cols; ++c) {
      if (std::isfinite(p[c]) && !(zero_is_none && p[c] == 0.0f)) v.push_back(p[c]);
    }
  }
  if (v.empty()) return false;
  const auto at = [&v](double pct) {
    const auto k =
        static_cast<size_t>(std::lround(std::min(1.0, std::max(0.0, pct / 100.0)) * (v.size() - 1)));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return static_cast<double>(v[k]);
  };
  *lo = at(low_pct);
  *hi = at(high_pct);
  if (!(*hi - *lo > 1e-6)) {
    const double mid = 0.5 * (*lo + *hi);
    *lo = mid - 0.05;
    *hi = mid + 0.05;
  }
  return true;
}

cv::Mat DemPicture::colourLut(int colormap) {
  cv::Mat ramp(1, 256, CV_8UC1);
  for (int i = 0; i < 256; ++i) ramp.at<uchar>(0, i) = static_cast<uchar>(i);
  cv::Mat lut;
  cv::applyColorMap(ramp, lut, colormap);
  return lut;
}

cv::Mat DemPicture::traversabilityLut() {
  cv::Mat lut(1, 256, CV_8UC3);
  for (int i = 0; i < 256; ++i) {
    const double t = i / 255.0;
    // red (0) -> yellow (0.5) -> green (1), slightly darkened green so text stays readable
    const double r = t < 0.5 ? 230.0 : 230.0 * (1.0 - t) * 2.0;
    const double g = t < 0.5 ? 40.0 + 170.0 * t * 2.0 : 210.0 - 30.0 * (t - 0.5) * 2.0;
    const double b = 30.0;
    lut.at<cv::Vec3b>(0, i) =
        cv::Vec3b(cv::saturate_cast<uchar>(b), cv::saturate_cast<uchar>(g), cv::saturate_cast<uchar>(r));
  }
  return lut;
}

cv::Mat DemPicture::heightPicture(const cv::Mat& heights, const GroundGrid& grid,
                                  const DemPictureOptions& options,
                                  const std::vector<Eigen::Vector2d>& trajectory_xy_m,
                                  DemPictureLayout* layout) {
  checkInputs("DemPicture::heightPicture", heights, grid, options);
  double lo = options.min_value, hi = options.max_value;
  if (std::isnan(lo) || std::isnan(hi)) {
    double plo = 0.0, phi = 1.0;
    if (!robustRange(heights, options.low_percentile, options.high_percentile, &plo, &phi)) {
      plo = 0.0;
      phi = 1.0;
    }
    if (std::isnan(lo)) lo = std::isnan(hi) ? plo : std::min(plo, hi - 0.1);
    if (std::isnan(hi)) hi = std::max(phi, lo + 0.1);
  }
  const cv::Mat lut = colourLut(options.height_colormap);

  // Hill-shading: Lambert shading of the surface normal under a distant light, normalised so
  // that level ground keeps its colour.
  const double az = options.light_azimuth_deg * CV_PI / 180.0;
  const double el = options.light_elevation_deg * CV_PI / 180.0;
  // Towards the light: compass north = +x (up), east = -y (right).
  const Eigen::Vector3d light(std::cos(az) * std::cos(el), -std::sin(az) * std::cos(el), std::sin(el));
  const double res = grid.resolution_m;
  const auto z = [&heights](int r, int c) { return static_cast<double>(heights.at<float>(r, c)); };
  const auto slope = [&](int r, int c, int dr, int dc) {
    // central difference, one-sided next to unknown vertices or borders, 0 if isolated
    const bool fwd = grid.contains(r + dr, c + dc) && std::isfinite(z(r + dr, c + dc));
    const bool bwd = grid.contains(r - dr, c - dc) && std::isfinite(z(r - dr, c - dc));
    if (fwd && bwd) return (z(r + dr, c + dc) - z(r - dr, c - dc)) / (2.0 * res);
    if (fwd) return (z(r + dr, c + dc) - z(r, c)) / res;
    if (bwd) return (z(r, c) - z(r - dr, c - dc)) / res;
    return 0.0;
  };
  const cv::Vec3b unknown = options.unknown_bgr;
  const cv::Mat cells = orientedCells(grid, [&](int r, int c) {
    const double h = z(r, c);
    if (!std::isfinite(h)) return unknown;
    cv::Vec3b colour = lutAt(lut, (h - lo) / (hi - lo));
    if (options.hillshade && options.hillshade_strength > 0.0) {
      const double k = options.hillshade_z_factor;
      const Eigen::Vector3d n =
          Eigen::Vector3d(-k * slope(r, c, 0, 1), -k * slope(r, c, 1, 0), 1.0).normalized();
      const double shade = std::max(0.0, n.dot(light)) / std::sin(el);
      const double f = (1.0 - options.hillshade_strength) + options.hillshade_strength * shade;
      for (int ch = 0; ch < 3; ++ch) colour[ch] = cv::saturate_cast<uchar>(colour[ch] * f);
    }
    return colour;
  });
  const std::string title =
      options.title.empty() ? "Ground elevation, " + resolutionText(grid) : options.title;
  return composeMap(cells, grid, options, title, "height [m]", lut, lo, hi, " m", trajectory_xy_m, layout);
}

cv::Mat DemPicture::traversabilityPicture(const cv::Mat& traversability, const GroundGrid& grid,
                                          const DemPictureOptions& options,
                                          const std::vector<Eigen::Vector2d>& trajectory_xy_m,
                                          DemPictureLayout* layout) {
  checkInputs("DemPicture::traversabilityPicture", traversability, grid, options);
  const cv::Mat lut = traversabilityLut();
  const cv::Vec3b unknown = options.unknown_bgr;
  const cv::Mat cells = orientedCells(grid, [&](int r, int c) {
    const double t = traversability.at<float>(r, c);
    return std::isfinite(t) ? lutAt(lut, t) : unknown;
  });
  const std::string title = options.title.empty() ? "Traversability, " + resolutionText(grid) : options.title;
  return composeMap(cells, grid, options, title, "traversability (1 = free)", lut, 0.0, 1.0, "",
                    trajectory_xy_m, layout);
}

cv::Mat DemPicture::overlayOnImage(const cv::Mat& image, const cv::Mat& values, double min_value,
                                   double max_value, const std::string& legend_title,
                                   const DemPictureOptions& options) {
  std::string why;
  if (!options.isValid(&why))
    throw std::invalid_argument("DemPicture::overlayOnImage: invalid options: " + why);
  GreyConverterOptions any_size;  // a picture of any image size
  any_size.min_side_px = 1;
  any_size.max_side_px = std::numeric_limits<int>::max();
  any_size.max_megapixels = std::numeric_limits<double>::max();
  const std::string bad_image = GreyConverter::check(image, any_size);
  if (!bad_image.empty()) throw std::invalid_argument("DemPicture::overlayOnImage: " + bad_image);
  if (values.type() != CV_32FC1 || values.size() != image.size()) {
    throw std::invalid_argument("DemPicture::overlayOnImage: values are not CV_32F of the image size");
  }
  double lo = min_value, hi = max_value;
  if (std::isnan(lo) || std::isnan(hi)) {
    double plo = 0.0, phi = 1.0;
    if (!robustRange(values, options.low_percentile, options.high_percentile, &plo, &phi, true)) {
      plo = 0.0;
      phi = 1.0;
    }
    if (std::isnan(lo)) lo = std::isnan(hi) ? plo : std::min(plo, hi - 1e-3);
    if (std::isnan(hi)) hi = std::max(phi, lo + 1e-3);
  }
  if (!(hi > lo)) throw std::invalid_argument("DemPicture::overlayOnImage: empty value range");
  cv::Mat base = GreyConverter::toBgr8(image, options.image_bit_depth);
  const cv::Mat lut = colourLut(options.overlay_colormap);
  const double a = options.overlay_alpha;
  for (int r = 0; r < base.rows; ++r) {
    const float* v = values.ptr<float>(r);
    cv::Vec3b* p = base.ptr<cv::Vec3b>(r);
    for (int c = 0; c < base.cols; ++c) {
      if (!std::isfinite(v[c]) || v[c] == 0.0f) continue;
      const cv::Vec3b col = lutAt(lut, (v[c] - lo) / (hi - lo));
      for (int ch = 0; ch < 3; ++ch) p[c][ch] = cv::saturate_cast<uchar>(a * col[ch] + (1.0 - a) * p[c][ch]);
    }
  }
  const int strip_h = 58;
  const int title_w = textSize(legend_title).width;
  const int width = std::max(base.cols, title_w + 3 * kMargin + 160);
  cv::Mat canvas(base.rows + strip_h, width, CV_8UC3, kPaper);
  base.copyTo(canvas(cv::Rect(0, 0, base.cols, base.rows)));
  text(canvas, legend_title, {kMargin, base.rows + 26});
  const int bar_x = kMargin + title_w + 2 * kMargin;
  const int bar_w = std::max(120, std::min(420, width - bar_x - 2 * kMargin));
  drawHorizontalBar(canvas, cv::Rect(bar_x, base.rows + 12, bar_w, 16), lut, lo, hi, ticksFor(lo, hi));
  return canvas;
}

void DemPicture::save(const std::string& path, const cv::Mat& picture) {
  bool ok = false;
  try {
    ok = !picture.empty() && cv::imwrite(path, picture);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("DemPicture: " + path + ": cannot write: " + e.err);
  }
  if (!ok)
    throw std::runtime_error("DemPicture: " + path +
                             ": cannot write (empty picture, unknown extension or unwritable directory)");
}

}  // namespace stereo_ground_dem
