// cairn::util's parallel loop and cairn::util_image's image writer.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <thread>
#include <vector>

#include "cairn/od/parallel.hpp"
#include "cairn/util/image_file.hpp"

namespace fs = std::filesystem;
using cairn::od::ParallelFor;

TEST(ParallelFor, CallsEveryItemOnceOnTheThreadsItReports) {
  for (const int count : {0, 1, 3, 7, 1000}) {
    for (const int threads : {1, 2, 0, 8}) {
      std::vector<std::atomic<int>> calls(count);
      std::atomic<int> highest_worker{0};
      const int used = ParallelFor(count, threads, [&](int worker, int item) {
        ++calls[item];
        int seen = highest_worker.load();
        while (worker > seen && !highest_worker.compare_exchange_weak(seen, worker)) {
        }
      });
      EXPECT_GE(used, 1);
      EXPECT_LE(used, std::max(1, count / 4));  // one thread per chunk of 4 items at most
      if (threads > 0) {
        EXPECT_LE(used, threads);
      }
      EXPECT_LT(highest_worker.load(), used);
      for (int i = 0; i < count; ++i) {
        EXPECT_EQ(calls[i].load(), 1) << "item " << i << " of " << count << ", threads " << threads;
      }
    }
  }
  std::vector<int> squares(100, 0);  // the one-argument form
  ParallelFor(100, 2, [&](int i) { squares[i] = i * i; });
  for (int i = 0; i < 100; ++i) EXPECT_EQ(squares[i], i * i);
}

// The pool's threads serve loops called from several threads at once and from inside a
// loop's body; each call sees every item once and returns after all of them.
TEST(ParallelFor, LoopsFromSeveralThreadsAndInsideLoopsEachCallEveryItemOnce) {
  constexpr int kOuter = 16, kInner = 200;
  const auto nested = [&](std::vector<std::atomic<int>>& calls) {
    ParallelFor(
        kOuter, 3,
        [&](int outer) {
          ParallelFor(
              kInner, 2, [&](int inner) { ++calls[outer * kInner + inner]; }, 1);
        },
        1);
  };
  std::vector<std::atomic<int>> a(kOuter * kInner), b(kOuter * kInner);
  for (int round = 0; round < 20; ++round) {
    for (auto& c : a) c = 0;
    for (auto& c : b) c = 0;
    std::thread other([&] { nested(b); });
    nested(a);
    other.join();
    for (int i = 0; i < kOuter * kInner; ++i) {
      ASSERT_EQ(a[i].load(), 1) << "round " << round << ", item " << i;
      ASSERT_EQ(b[i].load(), 1) << "round " << round << ", item " << i;
    }
  }
}

// A body that throws on the calling thread, or on a helper: the exception reaches the caller
// once the helpers have let go of the loop, and the pool serves the next loop. (In the first
// case a helper holds its first item until the caller has one, so that the caller is sure to
// run an item.)
TEST(ParallelFor, AnExceptionFromTheBodyReachesTheCaller) {
  for (int round = 0; round < 20; ++round) {
    std::atomic<int> calls{0};
    std::atomic<bool> caller_has_one{false};
    EXPECT_THROW(ParallelFor(
                     64, 2,
                     [&](int worker, int) {
                       ++calls;
                       if (worker == 0) {
                         caller_has_one = true;
                         throw std::runtime_error("item failed");
                       }
                       while (!caller_has_one) std::this_thread::yield();
                     },
                     1),
                 std::runtime_error);
    EXPECT_GE(calls.load(), 1);
  }
  // Thrown on whichever thread runs the item: a helper's exception reaches the caller too.
  for (int round = 0; round < 20; ++round) {
    EXPECT_THROW(ParallelFor(
                     64, 2,
                     [&](int item) {
                       if (item == 37) throw std::runtime_error("item 37 failed");
                     },
                     1),
                 std::runtime_error);
  }
  std::vector<int> squares(100, 0);
  ParallelFor(100, 2, [&](int i) { squares[i] = i * i; });
  for (int i = 0; i < 100; ++i) EXPECT_EQ(squares[i], i * i);
}

TEST(WriteImageAtomic, WritesWhatOpenCvReadsBackAndKeepsTheOldFileOnFailure) {
  const fs::path dir =
      fs::temp_directory_path() / ("cairn_util_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path png = dir / "image.png";
  cv::Mat image(5, 7, CV_16UC1);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c)
      image.at<std::uint16_t>(r, c) = static_cast<std::uint16_t>(1000 * r + c);
  }
  ASSERT_TRUE(cairn::util::WriteImageAtomic(png, image).ok());
  const cv::Mat back = cv::imread(png.string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(back.type(), CV_16UC1);
  EXPECT_EQ(cv::countNonZero(back != image), 0);

  // An image PNG cannot hold: the error names the file, the format and the type; the file
  // written before is intact and no temporary is left.
  const cv::Mat unsupported(3, 3, CV_64FC2, cv::Scalar(1.0, 2.0));
  const cairn::Status s = cairn::util::WriteImageAtomic(png, unsupported);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find(png.string()), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("PNG encoding failed"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("64-bit float 2-channel"), std::string::npos) << s.message();
  EXPECT_EQ(cv::countNonZero(cv::imread(png.string(), cv::IMREAD_UNCHANGED) != image), 0);
  int files = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 1);

  const cairn::Status missing =
      cairn::util::WriteImageAtomic(dir / "no" / "such.tiff", image, ".tiff");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find("such.tiff"), std::string::npos) << missing.message();
  fs::remove_all(dir);
}
