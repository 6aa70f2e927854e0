// The evaluation's figures, in the paper's style, as images in memory and as PNG files.
//
//  - Comparison: per frame, a column for the truth and one per method. The upper row is the
//    grey depth (near bright) with kept obstacle points blue and rejected ones red (truth:
//    obstacle objects blue, their foot band cyan, other objects yellow); the lower row gives
//    each segment its colour (truth: each object). Every column is captioned with the
//    method and its scores on that frame.
//  - Precision-recall curve of a sweep: one curve per method, points in sweep order, the
//    first and last labelled with their value.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "cairn/eval/methods.hpp"
#include "cairn/eval/sweep.hpp"
#include "cairn/eval/truth.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/io/detection_files.hpp"

namespace cairn::eval {

struct FigureOptions {
  int cell_width = 320;  ///< frames wider than this are scaled down to it [px]
};

/// One frame's strip of a comparison figure (see above). Fails when `evaluation` does not
/// hold one run and one score per method, or sizes disagree.
Expected<od::io::RgbImage> ComparisonStrip(const EvalFrame& frame,
                                           const FrameEvaluation& evaluation,
                                           const std::vector<Method>& methods,
                                           const FigureOptions& options = {});

/// Strips stacked under a title and above the colour legend (strips of different widths
/// are left-aligned on white).
od::io::RgbImage ComparisonFigure(const std::string& title,
                                  const std::vector<od::io::RgbImage>& strips);

/// Precision (foot band excluded) against recall, per point, for each method over the
/// sweep's values; `scores` is [value][method], summed over the frames of interest.
od::io::RgbImage PrecisionRecallPlot(const SweepSpec& sweep, const std::vector<Method>& methods,
                                     const SweepScores& scores, const std::string& title);

/// Writes an image as PNG, atomically. Errors name the file.
Status WritePng(const std::filesystem::path& path, const od::io::RgbImage& image);

}  // namespace cairn::eval
