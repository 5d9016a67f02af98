// The number-format exploration: the same scene, seed and samples in every format, each compared with a double
// render of the same (equally scaled) scene, written as a table, a plot of error against bits and the images.
#include "app/numerics.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>

#include <fmt/format.h>

#include "app/image_size.hpp"
#include "backends/registry.hpp"
#include "base/atomic_file.hpp"
#include "base/number_formats.hpp"
#include "film/film.hpp"
#include "loading/scene_loader.hpp"

namespace pt {
namespace {

bool is_fixed_name(const std::string& format) { return !format.empty() && format[0] == 'q'; }

struct Row {
  std::string format;
  int bits = 0;
  double scale = 1;
  bool rendered = false;
  std::string failure;  // why the format could not render the scene
  double rmse = 0, psnr = 0, visible_share = 0;
  u64 saturations = 0;
  double seconds = 0;
  LinearImage image;
};

// The value a PNG would store, as a fraction of full scale: clamped, sRGB encoded.
double display(float linear) {
  if (!std::isfinite(linear)) return 0;
  return linear_to_srgb(std::clamp(linear, 0.0f, 1.0f));
}

// RMSE and PSNR of the display values, and the share of pixels where some channel is more than one 8-bit step off.
void compare(const LinearImage& image, const LinearImage& reference, Row& row) {
  double squared = 0;
  std::size_t visible = 0;
  const std::size_t pixels = static_cast<std::size_t>(image.width) * image.height;
  for (std::size_t p = 0; p < pixels; ++p) {
    long worst_step = 0;
    for (int c = 0; c < 3; ++c) {
      const double a = display(image.rgb[3 * p + c]), b = display(reference.rgb[3 * p + c]);
      squared += (a - b) * (a - b);
      worst_step = std::max(worst_step, std::labs(std::lround(a * 255) - std::lround(b * 255)));
    }
    if (worst_step > 1) ++visible;
  }
  row.rmse = std::sqrt(squared / (3.0 * pixels));
  row.psnr = row.rmse > 0 ? 20 * std::log10(1 / row.rmse) : std::numeric_limits<double>::infinity();
  row.visible_share = static_cast<double>(visible) / pixels;
}

template <class T>
RenderResult render_in(const SceneDescription& scene, const RenderSettings& settings, Integrator integrator, double scale, unsigned threads,
                       double& used_scale) {
  const FlatScene<T> flat = flatten_scene<T>(scene, settings, scale);
  used_scale = flat.scale;
  auto backend = make_backend<T>("cpu", threads, 0, integrator);
  return render_scene(*backend, flat);
}

std::string psnr_text(double psnr) { return std::isinf(psnr) ? "inf" : fmt::format("{:.2f}", psnr); }

// Error (PSNR, higher is better) against total bits; formats that could not render sit on the axis as crosses.
std::string plot_svg(const std::vector<Row>& rows, const std::string& title) {
  const double left = 70, right = 620, top = 40, bottom = 360, min_bits = 0, max_bits = 72;
  double max_psnr = 60;
  for (const Row& r : rows)
    if (r.rendered && std::isfinite(r.psnr)) max_psnr = std::max(max_psnr, std::ceil(r.psnr / 10) * 10);
  const double ceiling = max_psnr + 10;  // identical images (infinite PSNR) are drawn on this line
  auto x_of = [&](double bits) { return left + (bits - min_bits) / (max_bits - min_bits) * (right - left); };
  auto y_of = [&](double psnr) { return bottom - std::clamp(psnr, 0.0, ceiling) / ceiling * (bottom - top); };
  std::string svg = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"680\" height=\"420\" font-family=\"sans-serif\" font-size=\"12\">\n"
      "<rect width=\"680\" height=\"420\" fill=\"white\"/>\n<text x=\"{}\" y=\"22\" font-size=\"14\">{}</text>\n",
      left, title);
  svg += fmt::format(
      "<line x1=\"{0}\" y1=\"{1}\" x2=\"{2}\" y2=\"{1}\" stroke=\"black\"/><line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{3}\" stroke=\"black\"/>\n",
      left, bottom, right, top);
  for (int bits = 0; bits <= 72; bits += 8)
    svg += fmt::format(
        "<line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"#ddd\"/><text x=\"{0}\" y=\"{3}\" text-anchor=\"middle\">{4}</text>\n",
        x_of(bits), bottom, top, bottom + 16, bits);
  for (double p = 0; p <= ceiling; p += 10)
    svg +=
        fmt::format("<line x1=\"{0}\" y1=\"{1}\" x2=\"{2}\" y2=\"{1}\" stroke=\"#ddd\"/><text x=\"{3}\" y=\"{4}\" text-anchor=\"end\">{5}</text>\n",
                    left, y_of(p), right, left - 6, y_of(p) + 4, p >= ceiling ? std::string("inf") : fmt::format("{:.0f}", p));
  svg += fmt::format("<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">bits per value</text>\n", (left + right) / 2, bottom + 34);
  svg += fmt::format("<text x=\"18\" y=\"{0}\" transform=\"rotate(-90 18 {0})\" text-anchor=\"middle\">PSNR against double (dB)</text>\n",
                     (top + bottom) / 2);
  int label = 0;
  for (const Row& r : rows) {
    if (r.format == "double") continue;  // the reference itself
    const double x = x_of(r.bits), dy = (label++ % 2) ? 14 : -8;
    if (!r.rendered) {
      const double y = bottom;
      svg += fmt::format("<path d=\"M{} {} l8 8 m0 -8 l-8 8\" stroke=\"#c00\"/><text x=\"{}\" y=\"{}\" fill=\"#c00\">{} (does not fit)</text>\n",
                         x - 4, y - 4, x + 6, y - 10 - 14 * (label % 3), r.format);
      continue;
    }
    const double y = y_of(std::isfinite(r.psnr) ? r.psnr : ceiling);
    const char* colour = is_fixed_name(r.format) ? "#1f5fbf" : "#2a2";
    svg += fmt::format("<circle cx=\"{}\" cy=\"{}\" r=\"4\" fill=\"{}\"/><text x=\"{}\" y=\"{}\">{}</text>\n", x, y, colour, x + 6, y + dy, r.format);
  }
  svg += "</svg>\n";
  return svg;
}

// Before any rendering, so that a file where the folder should be is reported at once.
void check_output_folder(const std::filesystem::path& folder) {
  std::error_code error;
  if (std::filesystem::exists(folder, error) && !std::filesystem::is_directory(folder, error))
    throw InputError(fmt::format("{}: cannot write the results: it is a file, not a folder", folder.string()));
}

// The output folder, made if missing; returns whether it was.
bool make_output_folder(const std::filesystem::path& folder) {
  check_output_folder(folder);
  std::error_code error;
  const bool created = std::filesystem::create_directories(folder, error);
  if (error) throw InputError(fmt::format("{}: cannot create the folder: {}", folder.string(), error.message()));
  return created;
}

// All or nothing: the files are complete and synced under temporary names beside their final ones before the
// first rename, so a full disk or a failing write (the likely failures) leaves the folder as it was. The renames
// then only fail if the folder is changed under the program; should one fail, the files not yet renamed are
// removed and the error reported (a folder cannot be replaced whole without losing files others put in it).
void publish_all(std::vector<AtomicFile>& files) {
  for (AtomicFile& file : files) file.publish();
}

void write_results(const std::filesystem::path& folder, const SceneDescription& scene, const RenderSettings& settings, const std::vector<Row>& rows,
                   std::vector<AtomicFile>& files);

}  // namespace

int run_numerics(const NumericsOptions& options) {
  // The command line's mistakes first: they cost nothing to find.
  check_image_size(options.width, options.height, fmt::format("--width {} --height {}", options.width, options.height));
  check_output_folder(options.output_folder);
  const SceneDescription scene = load_scene_file(options.scene, model_references(options.trust_model_paths));
  RenderSettings settings = scene.render;
  settings.width = options.width;
  settings.height = options.height;
  settings.samples_per_pixel = options.spp;
  if (options.depth) settings.max_depth = *options.depth;
  if (options.seed) settings.seed = *options.seed;
  const Integrator integrator = options.bidirectional ? Integrator::kBidirectional : Integrator::kMegakernel;
  const std::vector<std::string> formats = options.formats.empty() ? number_format_names() : options.formats;

  // Double renders of the scene at each scale a format needed: the reference for every format at that scale.
  std::map<double, LinearImage> references;
  auto reference_at = [&](double scale) -> const LinearImage& {
    auto found = references.find(scale);
    if (found != references.end()) return found->second;
    double used = 0;
    return references.emplace(scale, render_in<double>(scene, settings, integrator, scale, options.threads, used).image).first->second;
  };

  std::vector<Row> rows;
  for (const std::string& name : formats) {
    Row row;
    row.format = name;
    with_number_format(name, [&]<class T>() {
      row.bits = number_format_bits<T>();
      try {
        const RenderResult result = render_in<T>(scene, settings, integrator, 0, options.threads, row.scale);
        row.rendered = true;
        row.image = result.image;
        row.seconds = result.stats.seconds;
        row.saturations = result.stats.saturations;
      } catch (const InputError& e) {
        row.failure = e.what();
      }
    });
    if (row.rendered) compare(row.image, reference_at(row.scale), row);
    fmt::print(stderr, "{}: {}\n", name, row.rendered ? fmt::format("PSNR {} dB, {:.3f} s", psnr_text(row.psnr), row.seconds) : row.failure);
    rows.push_back(std::move(row));
  }

  // Every file is made complete on disk under a temporary name before any takes its place (publish_all below).
  std::vector<AtomicFile> files;
  const std::filesystem::path folder = options.output_folder;
  const bool created_folder = make_output_folder(folder);
  try {
    write_results(folder, scene, settings, rows, files);
    publish_all(files);
  } catch (...) {
    files.clear();  // the temporaries go
    std::error_code ignored;
    if (created_folder) std::filesystem::remove(folder, ignored);  // only if still empty: it was made for this run
    throw;
  }
  std::string order;
  for (const Row& r : rows)
    if (r.rendered) order += (order.empty() ? "" : ", ") + r.format;
  if (!order.empty())
    fmt::print(stderr, "wrote {}: numerics.csv, error-vs-bits.svg, side-by-side.png ({}) and one PNG per format\n", folder.string(), order);
  return 0;
}

namespace {

// The table (to stdout and numerics.csv), the plot and the images, each written to its temporary in `files`.
void write_results(const std::filesystem::path& folder, const SceneDescription& scene, const RenderSettings& settings, const std::vector<Row>& rows,
                   std::vector<AtomicFile>& files) {
  std::string csv = "scene,format,bits,scale,rmse,psnr_db,visible_share,saturations,seconds,status\n";
  const std::string table_head = fmt::format("{:<8} {:>4} {:>10} {:>10} {:>9} {:>9} {:>12} {:>8}  {}\n", "format", "bits", "scale", "rmse", "psnr_db",
                                             "visible%", "saturations", "seconds", "status");
  std::string table = table_head;
  for (const Row& r : rows) {
    const std::string status = r.rendered ? "ok" : r.failure;
    std::string quoted = status;
    std::replace(quoted.begin(), quoted.end(), '"', '\'');
    if (r.rendered) {
      csv += fmt::format("{},{},{},{:g},{:.6g},{},{:.6g},{},{:.4f},ok\n", scene.source, r.format, r.bits, r.scale, r.rmse, psnr_text(r.psnr),
                         r.visible_share, r.saturations, r.seconds);
      table += fmt::format("{:<8} {:>4} {:>10g} {:>10.6f} {:>9} {:>9.3f} {:>12} {:>8.3f}  ok\n", r.format, r.bits, r.scale, r.rmse, psnr_text(r.psnr),
                           100 * r.visible_share, r.saturations, r.seconds);
      files.push_back(write_image_unpublished(folder / (r.format + ".png"), rows_of(r.image)));
    } else {
      csv += fmt::format("{},{},{},,,,,,,\"{}\"\n", scene.source, r.format, r.bits, quoted);
      table += fmt::format("{:<8} {:>4} {:>10} {:>10} {:>9} {:>9} {:>12} {:>8}  does not fit\n", r.format, r.bits, "-", "-", "-", "-", "-", "-");
    }
  }
  fmt::print("{}", table);
  files.push_back(write_file_unpublished(folder / "numerics.csv", "the table", csv));
  files.push_back(write_file_unpublished(folder / "error-vs-bits.svg", "the plot",
                                         plot_svg(rows, fmt::format("{}: {}x{}, {} spp", std::filesystem::path(scene.source).filename().string(),
                                                                    settings.width, settings.height, settings.samples_per_pixel))));

  // Every rendered format left to right in table order, 4 black pixels apart.
  std::vector<const Row*> shown;
  for (const Row& r : rows)
    if (r.rendered) shown.push_back(&r);
  if (!shown.empty()) {
    const u32 gap = 4, w = settings.width, h = settings.height;
    LinearImage strip;
    strip.width = static_cast<u32>(shown.size()) * (w + gap) - gap;
    strip.height = h;
    strip.rgb.assign(static_cast<std::size_t>(strip.width) * h * 3, 0.0f);
    for (std::size_t i = 0; i < shown.size(); ++i)
      for (u32 y = 0; y < h; ++y)
        std::copy_n(&shown[i]->image.rgb[static_cast<std::size_t>(y) * w * 3], w * 3,
                    &strip.rgb[(static_cast<std::size_t>(y) * strip.width + i * (w + gap)) * 3]);
    files.push_back(write_image_unpublished(folder / "side-by-side.png", rows_of(strip)));
  }
}

}  // namespace
}  // namespace pt
