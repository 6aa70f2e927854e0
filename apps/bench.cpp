// cairn bench: how fast the detectors run on the user's own frame, as medians of repeated
// runs, each as a ratio to the exact cone detector on one thread measured in the same run,
// against the time a sensor rate leaves per frame. The exact detector's result is checked
// against the region scan (the earlier exact method, kept as the reference) and against the
// O(N^2) definition when the frame is small enough (or --brute-force).
// Given a sequence instead (--rawlog, --kitti, --frames), it runs the Mapper over it as
// `cairn map` does and times every stage (bench_sequence.cpp).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <chrono>
#include <functional>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cairn/od/column_detector.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/util/format.hpp"
#include "detect.hpp"
#include "subcommands.hpp"
#if CAIRN_HAVE_MAP
#include "bench_sequence.hpp"
#endif

namespace cairn::apps {
namespace {

struct BenchOptions {
  DetectOptions input;  ///< --depth/--intrinsics or --points (with --sensor ...), --config
  int repeat = 5;
  double rate_hz = 10.0;
  bool brute_force = false;
  // A sequence (bench_sequence.cpp): one of these, with --config, --intrinsics, --sensor.
  std::string rawlog, kitti, kitti_sequence, kitti_range, frames, poses, tilt;
  int max_frames = 0;
};

/// Brute force runs by default up to this many valid points (about 2 s).
constexpr int kBruteForceAuto = 20000;

struct Timing {
  std::string method;
  std::vector<double> ms;
  od::Detection last;
  double median() const {
    std::vector<double> v = ms;
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v.size() % 2 ? v[v.size() / 2]
                                          : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
  }
};

int BenchFail(const std::string& message) { return CommandFailure("bench", message); }

int RunBench(const BenchOptions& o) {
  const int inputs = !o.input.points.empty() + !o.input.depth.empty() + !o.rawlog.empty() +
                     !o.kitti.empty() + !o.frames.empty();
  if (inputs != 1) {
    return BenchFail(
        "give one input: a frame (--depth FILE --intrinsics FILE.yaml, or --points FILE) or a "
        "sequence (--rawlog FILE, --kitti DIR, or --frames DIR --poses FILE.tum --intrinsics "
        "FILE.yaml)");
  }
  if (o.input.points.empty() && o.input.depth.empty()) {
#if CAIRN_HAVE_MAP
    MapOptions m;
    m.rawlog = o.rawlog;
    m.kitti = o.kitti;
    m.sequence = o.kitti_sequence;
    m.range = o.kitti_range;
    if (!o.input.sensor.empty()) m.lidar = o.input.sensor;
    m.frames = o.frames;
    m.poses = o.poses;
    m.intrinsics = o.input.intrinsics;
    m.config = o.input.config;
    m.tilt = o.tilt;
    m.max_frames = o.max_frames;
    return RunSequenceBench(m, o.rate_hz);
#else
    return BenchFail("this cairn was built without the Mapper: a sequence cannot be timed");
#endif
  }
  Expected<od::io::DetectSettings> settings = LoadDetectSettingsOrDefaults(o.input);
  if (!settings) return BenchFail(settings.error().message);
  od::RangeImage image;
  std::string what;
  if (!o.input.points.empty()) {
    Expected<sources::FileFrame> scan = ReadScanInput(o.input);
    if (!scan) return BenchFail(scan.error().message);
    image = std::move(scan->image);
    what = o.input.points;
  } else {
    Expected<sources::FileFrame> depth = ReadDepthInput(o.input);
    if (!depth) return BenchFail(depth.error().message);
    image = std::move(depth->image);
    what = o.input.depth;
  }

  const auto time = [&](const std::string& name, auto&& run) -> Expected<Timing> {
    Timing t;
    t.method = name;
    for (int k = 0; k < o.repeat; ++k) {
      const auto start = std::chrono::steady_clock::now();
      Expected<od::Detection> d = run();
      t.ms.push_back(1e3 * util::SecondsSince(start));
      if (!d) return Error{name + ": " + d.error().message};
      t.last = std::move(*d);
    }
    return t;
  };
  od::DetectorConfig all = settings->detector;  // exact, with the settings' threads
  all.search = od::SearchMode::kExact;
  od::DetectorConfig one = all;
  one.threads = 1;
  od::DetectorConfig window = one;
  window.search = od::SearchMode::kPaperWindow;
  od::ColumnConfig column = od::ColumnConfig::From(settings->detector);
  column.min_blob_pixels = settings->min_blob_pixels;

  // The quick methods run in turn, one run of each per round: the machine may be shared, and a
  // change in its load then falls on each of them alike (above all on the ratio of the two exact
  // rows). The slow references follow, each in a block.
  const std::string threads =
      all.threads > 0 ? std::to_string(all.threads) + " threads" : "every core";
  const std::array<std::pair<std::string, std::function<Expected<od::Detection>()>>, 3> quick = {{
      {"cone exact, 1 thread", [&] { return od::Detect(image, one); }},
      {"cone exact, " + threads, [&] { return od::Detect(image, all); }},
      {"column baseline", [&] { return od::DetectColumns(image, column); }},
  }};
  std::array<Timing, 3> in_turn;
  for (std::size_t q = 0; q < quick.size(); ++q) in_turn[q].method = quick[q].first;
  for (int k = 0; k < o.repeat; ++k) {
    for (std::size_t q = 0; q < quick.size(); ++q) {
      const auto start = std::chrono::steady_clock::now();
      Expected<od::Detection> d = quick[q].second();
      in_turn[q].ms.push_back(1e3 * util::SecondsSince(start));
      if (!d) return BenchFail(quick[q].first + ": " + d.error().message);
      in_turn[q].last = std::move(*d);
    }
  }
  std::cerr << "cairn bench: cone exact (1 thread, " << threads
            << ") and column baseline done, in turn\n";
  std::vector<Timing> rows;
  rows.push_back(std::move(in_turn[0]));
  rows.push_back(std::move(in_turn[1]));
  const auto add = [&](const std::string& name, auto&& run) -> Status {
    Expected<Timing> t = time(name, run);
    if (!t) return t.error();
    rows.push_back(std::move(*t));
    std::cerr << "cairn bench: " << name << " done\n";
    return {};
  };
  if (Status s = add("region scan (reference)", [&] { return od::DetectRegionScan(image, one); });
      !s) {
    return BenchFail(s.message());
  }
  if (Status s = add("cone paper window, 1 thread", [&] { return od::Detect(image, window); });
      !s) {
    return BenchFail(s.message());
  }
  rows.push_back(std::move(in_turn[2]));
  // Same obstacle points, segments and feet.
  const auto same_as = [](const od::Detection& a, const od::Detection& b) {
    return a.labels == b.labels && a.foot == b.foot;
  };
  bool same = same_as(rows[0].last, rows[2].last) && same_as(rows[1].last, rows[2].last);
  const bool brute = o.brute_force || image.valid_count() <= kBruteForceAuto;
  if (brute) {
    if (Status s = add("brute force (the definition)",
                       [&] { return od::DetectBruteForce(image, one); });
        !s) {
      return BenchFail(s.message());
    }
    same = same && same_as(rows[0].last, rows.back().last);
  }

  const double reference_ms = rows[0].median();
  const double budget_ms = 1000.0 / o.rate_hz;
  std::cout << std::fixed << "cairn bench: " << what << " (" << image.width() << "x"
            << image.height() << ", " << image.valid_count() << " valid points), "
            << o.repeat << " runs each, medians\n";
  std::cout << "  " << std::left << std::setw(30) << "method" << std::right << std::setw(12)
            << "median ms" << std::setw(12) << "min ms" << std::setw(10) << "ratio"
            << std::setw(16) << "pairs tested" << std::setw(14) << "found" << std::setw(10)
            << "segments"
            << "\n";
  for (const Timing& t : rows) {
    const double med = t.median();
    std::cout << "  " << std::left << std::setw(30) << t.method << std::right
              << std::setprecision(1) << std::setw(12) << med << std::setw(12)
              << *std::min_element(t.ms.begin(), t.ms.end()) << std::setprecision(2)
              << std::setw(9) << med / reference_ms << "x" << std::setw(16)
              << t.last.stats.pairs_tested << std::setw(14) << t.last.stats.pairs_compatible
              << std::setw(10) << t.last.segments.size() << "\n";
  }
  std::cout << std::setprecision(2) << "  cone exact, " << threads
            << " over 1 thread: " << rows[0].median() / rows[1].median()
            << "x as fast (their runs in turn)\n";
  std::cout << "  ratio: to the exact cone detector on 1 thread, measured in this run\n"
            << "  found: compatible pairs looked at (the exact detector skips those that can "
               "change nothing)\n";
  std::cout << "  exact = " << (brute ? "region scan = brute force: " : "region scan: ")
            << (same ? "yes" : "NO") << " (same obstacle points, segments and feet)\n";
  if (!brute) {
    std::cout << "  brute force skipped (" << image.valid_count() << " valid points > "
              << kBruteForceAuto << "; --brute-force runs it)\n";
  }
  const double fastest_exact = std::min(rows[0].median(), rows[1].median());
  std::cout << std::setprecision(1) << "  at " << o.rate_hz << " Hz a frame has " << budget_ms
            << " ms: the exact detector takes " << std::setprecision(2)
            << fastest_exact / budget_ms << " of it\n";
  return same ? kExitOk : kExitFailure;
}

}  // namespace

Subcommand AddBenchCommand(CLI::App& parent) {
  auto o = std::make_shared<BenchOptions>();
  CLI::App* app = parent.add_subcommand(
      "bench",
      "Time the detectors on one frame of yours (medians of repeated runs, ratios to the exact "
      "detector on one thread in the same run), checked against the O(N^2) definition; or "
      "every stage of the Mapper over a sequence of yours (median and 95th percentile per "
      "frame, frames per second, peak memory)");
  app->add_option("--depth", o->input.depth, "z-depth image (16-bit PNG or float TIFF)")
      ->type_name("FILE");
  app->add_option("--intrinsics", o->input.intrinsics, "camera YAML (with --depth)")
      ->type_name("FILE.yaml");
  app->add_option("--points", o->input.points, "LiDAR scan (.bin, PLY, text), as cairn detect")
      ->type_name("FILE");
  app->add_option("--sensor", o->input.sensor, "LiDAR preset (with --points)")
      ->transform(CLI::IsMember(SensorPresets(), CLI::ignore_case));
  app->add_option("--up", o->input.up, "gravity's up in the LiDAR frame (with --points)")
      ->capture_default_str();
  app->add_option("--config", o->input.config, "settings YAML (config/default.yaml)")
      ->type_name("FILE");
  app->add_option("--repeat", o->repeat, "runs of each method")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app->add_option("--rate", o->rate_hz, "sensor frame rate [Hz] for the time budget")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app->add_flag("--brute-force", o->brute_force,
                "also run the O(N^2) definition on a large frame (slow)");
  CLI::Option_group* seq = app->add_option_group(
      "sequence", "A whole sequence through the Mapper, as cairn map runs it, writing nothing");
  seq->add_option("--rawlog", o->rawlog, "MRPT rawlog")->type_name("FILE");
  seq->add_option("--kitti", o->kitti, "KITTI odometry folder (scans with poses)")
      ->type_name("DIR");
  seq->add_option("--sequence", o->kitti_sequence, "KITTI sequence NN of a KITTI root (--kitti)")
      ->type_name("NN");
  seq->add_option("--range", o->kitti_range, "KITTI scans A:B (--kitti)")->type_name("A:B");
  seq->add_option("--frames", o->frames, "folder of depth PNGs (with --poses, --intrinsics)")
      ->type_name("DIR");
  seq->add_option("--poses", o->poses, "TUM trajectory of --frames")->type_name("FILE.tum");
  seq->add_option("--tilt", o->tilt, "tilt mode: prior, refine_to_map or gravity (the config's)");
  seq->add_option("--max-frames", o->max_frames, "stop after this many frames (0: all)")
      ->check(CLI::NonNegativeNumber);
  app->footer("Exit 1 on bad input, or when the exact detector differs from the definition.");
  return {app, [o] { return RunBench(*o); }};
}

}  // namespace cairn::apps
