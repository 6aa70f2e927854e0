// Detector speed on rendered cross-country frames. Each frame is timed with the brute-force
// reference (small frames only), the exact cone search, the paper's window and the column
// baseline, so ratios come from one run on one machine. Quote medians:
//   cairn_detector_benchmark --benchmark_repetitions=5 --benchmark_report_aggregates_only
#include <benchmark/benchmark.h>

#include <cstdint>
#include <fstream>
#include <map>
#include <optional>
#include <vector>

#include "cairn/od/column_detector.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/sim/random_scene.hpp"
#include "cairn/sim/render.hpp"

namespace {

using cairn::od::RangeImage;

// A seeded random view rendered at width x (3/4 width), cached across benchmarks.
const RangeImage& Frame(int width) {
  static std::map<int, RangeImage> cache;
  auto it = cache.find(width);
  if (it != cache.end()) return it->second;
  cairn::sim::RandomSceneOptions options;
  options.width = width;
  options.height = width * 3 / 4;
  options.min_objects = options.max_objects = 12;
  const cairn::sim::RandomView view = cairn::sim::MakeRandomView(2002, options);
  const auto frame = cairn::sim::RenderDepth(view.scene, view.camera);
  auto image = RangeImage::FromDepth(frame->depth_m, frame->model, frame->up_optical);
  return cache.emplace(width, std::move(*image)).first->second;
}

void Report(benchmark::State& state, const cairn::od::Detection& d, const RangeImage& image) {
  state.counters["pixels"] = image.size();
  state.counters["pairs_tested"] = static_cast<double>(d.stats.pairs_tested);
  state.counters["obstacle_points"] = d.stats.obstacle_points;
  state.counters["segments"] = static_cast<double>(d.segments.size());
}

// Every benchmark but the threaded one runs on one core so that ratios compare methods.
void BM_BruteForce(benchmark::State& state) {
  const RangeImage& image = Frame(static_cast<int>(state.range(0)));
  cairn::od::DetectorConfig config;
  for (auto _ : state) {
    auto d = cairn::od::DetectBruteForce(image, config);
    benchmark::DoNotOptimize(d);
    Report(state, *d, image);
  }
}

// range(1): worker threads (1: one core; 0: every hardware thread).
void BM_DetectExact(benchmark::State& state) {
  const RangeImage& image = Frame(static_cast<int>(state.range(0)));
  cairn::od::DetectorConfig config;
  config.threads = static_cast<int>(state.range(1));
  for (auto _ : state) {
    auto d = cairn::od::Detect(image, config);
    benchmark::DoNotOptimize(d);
    Report(state, *d, image);
  }
}

void BM_DetectPaperWindow(benchmark::State& state) {
  const RangeImage& image = Frame(static_cast<int>(state.range(0)));
  cairn::od::DetectorConfig config;
  config.search = cairn::od::SearchMode::kPaperWindow;
  config.threads = 1;
  for (auto _ : state) {
    auto d = cairn::od::Detect(image, config);
    benchmark::DoNotOptimize(d);
    Report(state, *d, image);
  }
}

void BM_DetectColumns(benchmark::State& state) {
  const RangeImage& image = Frame(static_cast<int>(state.range(0)));
  const auto config = cairn::od::ColumnConfig::From(cairn::od::DetectorConfig{});
  for (auto _ : state) {
    auto d = cairn::od::DetectColumns(image, config);
    benchmark::DoNotOptimize(d);
    Report(state, *d, image);
  }
}

// The RELLIS-3D Ouster OS1-64 scan in ../shared/datasets (64 x 2048, organised: index =
// col * 64 + ring), or nothing when the folder is absent.
const RangeImage* RellisScan() {
  static const std::optional<RangeImage> scan = []() -> std::optional<RangeImage> {
    std::ifstream in(CAIRN_SHARED_DATASETS "/rellis3d-000104/os1_bin/000104.bin",
                     std::ios::binary);
    if (!in) return std::nullopt;
    std::vector<float> raw(131072 * 4);
    in.read(reinterpret_cast<char*>(raw.data()), raw.size() * sizeof(float));
    if (!in) return std::nullopt;
    std::vector<Eigen::Vector3f> points(131072);
    std::vector<std::int32_t> rows(points.size()), cols(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      points[i] = {raw[4 * i], raw[4 * i + 1], raw[4 * i + 2]};
      rows[i] = static_cast<std::int32_t>(i % 64);
      cols[i] = static_cast<std::int32_t>(i / 64);
    }
    auto model = cairn::od::SphericalModel::Preset("OS1-64", 2048);
    auto image = RangeImage::FromPoints(points, *model, Eigen::Vector3d::UnitZ(), rows, cols);
    if (!image) return std::nullopt;
    return std::move(*image);
  }();
  return scan ? &*scan : nullptr;
}

// range(0): 0 the cone detector (exact), 1 the column baseline; range(1): threads.
void BM_RellisLidar(benchmark::State& state) {
  const RangeImage* image = RellisScan();
  if (image == nullptr) {
    state.SkipWithError("../shared/datasets/rellis3d-000104 is absent");
    return;
  }
  cairn::od::DetectorConfig config;
  config.threads = static_cast<int>(state.range(1));
  for (auto _ : state) {
    auto d = state.range(0) == 0
                 ? cairn::od::Detect(*image, config)
                 : cairn::od::DetectColumns(*image, cairn::od::ColumnConfig::From(config));
    benchmark::DoNotOptimize(d);
    Report(state, *d, *image);
  }
}

BENCHMARK(BM_RellisLidar)
    ->Args({0, 1})
    ->Args({0, 0})
    ->Args({1, 1})
    ->ArgNames({"column", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_BruteForce)->Arg(80)->Arg(160)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DetectExact)
    ->ArgsProduct({{80, 160, 320, 640}, {1, 0}})
    ->ArgNames({"width", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_DetectPaperWindow)->Arg(80)->Arg(160)->Arg(320)->Arg(640)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DetectColumns)->Arg(80)->Arg(160)->Arg(320)->Arg(640)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
