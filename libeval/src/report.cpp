#include "cairn/eval/report.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/units.hpp"
#include "cairn/util/format.hpp"

namespace cairn::eval {
namespace {

// A table cell: the value with `decimals` digits, or empty when there is none (NaN).
std::string Cell(double value, int decimals) {
  return std::isfinite(value) ? util::Fixed(value, decimals) : std::string();
}

std::string Percent(double ratio) {
  return std::isfinite(ratio) ? Cell(100.0 * ratio, 0) + "%" : "-";
}

/// A CSV field, quoted when it holds a comma, a quote or a line break.
std::string CsvField(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string out = "\"";
  for (const char c : text) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string Number(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

std::string Lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

bool Mentions(const WorldScores& world, const std::vector<std::string>& words) {
  const std::string text = Lower(world.name + " " + world.description);
  for (const std::string& w : words) {
    if (text.find(w) != std::string::npos) return true;
  }
  return false;
}

std::string Found(const Score& s) {
  return std::to_string(s.objects_found) + "/" + std::to_string(s.objects_counted) + " (" +
         Percent(s.FoundRate()) + ")";
}

}  // namespace

std::string FormatRatio(double value) { return std::isfinite(value) ? Cell(value, 2) : "-"; }

std::string ResultsCsv(const std::vector<ResultRow>& rows) {
  std::string out =
      "world,method,label,frames,tp,fp,fn,precision,recall,f1,iou,band_pixels,band_fp,"
      "band_precision,band_f1,band_iou,objects_counted,objects_found,found_rate,objects_small,"
      "non_obstacles_counted,non_obstacles_marked,segments,kept_segments,false_obstacles,"
      "segments_per_object_mean,segments_per_object_max,objects_per_segment_mean,"
      "objects_per_segment_max,merged_segments,detect_ms_mean\n";
  for (const ResultRow& r : rows) {
    const Score& s = r.score;
    const std::vector<std::string> fields = {CsvField(r.world),
                                             r.method.key,
                                             CsvField(r.method.label),
                                             std::to_string(s.frames),
                                             std::to_string(s.strict.tp),
                                             std::to_string(s.strict.fp),
                                             std::to_string(s.strict.fn),
                                             Cell(s.strict.Precision(), 4),
                                             Cell(s.strict.Recall(), 4),
                                             Cell(s.strict.F1(), 4),
                                             Cell(s.strict.IoU(), 4),
                                             std::to_string(s.band_pixels),
                                             std::to_string(s.band_excluded.fp),
                                             Cell(s.band_excluded.Precision(), 4),
                                             Cell(s.band_excluded.F1(), 4),
                                             Cell(s.band_excluded.IoU(), 4),
                                             std::to_string(s.objects_counted),
                                             std::to_string(s.objects_found),
                                             Cell(s.FoundRate(), 4),
                                             std::to_string(s.objects_small),
                                             std::to_string(s.non_obstacles_counted),
                                             std::to_string(s.non_obstacles_marked),
                                             std::to_string(s.segments),
                                             std::to_string(s.kept_segments),
                                             std::to_string(s.false_obstacles),
                                             Cell(s.SegmentsPerObject(), 3),
                                             std::to_string(s.segments_per_object_max),
                                             Cell(s.ObjectsPerSegment(), 3),
                                             std::to_string(s.objects_per_segment_max),
                                             std::to_string(s.merged_segments),
                                             Cell(r.detect_ms, 1)};
    for (std::size_t k = 0; k < fields.size(); ++k) out += (k ? "," : "") + fields[k];
    out += "\n";
  }
  return out;
}

std::string ResultsMarkdown(const std::vector<ResultRow>& rows) {
  std::string out =
      "| world | method | P | R | F1 | IoU | P (no band) | F1 (no band) | IoU (no band) | "
      "found | false | seg/obj | obj/seg | ms |\n"
      "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | "
      "---: | ---: |\n";
  for (const ResultRow& r : rows) {
    const Score& s = r.score;
    const auto seg = [](double mean, int max) {
      return std::isfinite(mean) ? Cell(mean, 2) + " (" + std::to_string(max) + ")"
                                 : std::string("-");
    };
    out += "| " + r.world + " | " + r.method.label + " | " + FormatRatio(s.strict.Precision()) +
           " | " + FormatRatio(s.strict.Recall()) + " | " + FormatRatio(s.strict.F1()) + " | " +
           FormatRatio(s.strict.IoU()) + " | " + FormatRatio(s.band_excluded.Precision()) + " | " +
           FormatRatio(s.band_excluded.F1()) + " | " + FormatRatio(s.band_excluded.IoU()) + " | " +
           Found(s) + " | " + std::to_string(s.false_obstacles) + " / " +
           std::to_string(s.kept_segments) + " | " +
           seg(s.SegmentsPerObject(), s.segments_per_object_max) + " | " +
           seg(s.ObjectsPerSegment(), s.objects_per_segment_max) + " | " + Cell(r.detect_ms, 0) +
           " |\n";
  }
  return out;
}

std::string ResultsLegend(const ScoreOptions& o) {
  return "- **Per point** (obstacle points; a detected point is a pixel of a kept segment, a "
         "true one a valid pixel of an obstacle object): **P** precision, **R** recall, **F1**, "
         "**IoU** = TP / (TP + FP + FN), all *strict*: every terrain pixel a kept segment "
         "covers is a false positive.\n"
         "- **(no band)**: the same with the *foot band* left out: terrain pixels within "
         "min(|dh|, Hmax) / tan(theta) horizontally of a point of an obstacle object (dh its "
         "height above or below them). The paper's definition pairs that ground with the "
         "obstacle, so the detector marks it by design. Recall is the same both ways.\n"
         "- **found**: obstacle objects found / counted. An obstacle object is counted when "
         "at least " +
         std::to_string(o.min_object_pixels) + " of its pixels are valid, found when at least " +
         Percent(o.found_fraction) +
         " of them are detected points.\n"
         "- **false**: false obstacles / kept segments. A kept segment is a false obstacle "
         "when less than " +
         Percent(o.false_fraction) +
         " of its pixels lie on obstacle objects or in their foot bands.\n"
         "- **seg/obj**: kept segments per found object, mean (max); **obj/seg**: obstacle "
         "objects per true kept segment, mean (max). A segment and an object are linked when "
         "they share at least " +
         Percent(o.link_fraction) +
         " of the smaller of the object's detected pixels and the segment's pixels. 1 (1) and "
         "1 (1) is a perfect segmentation.\n"
         "- **ms**: detection time per frame (methods that differ only by the rules share a "
         "detection).\n";
}

std::string SweepCsv(const SweepSpec& sweep, const std::vector<Method>& methods,
                     const std::vector<SweepRows>& rows) {
  const std::vector<double> values = sweep.Values();
  std::string out =
      "world,parameter,value,method,frames,tp,fp,fn,precision,recall,f1,band_fp,"
      "band_precision,band_f1,objects_counted,objects_found,found_rate,kept_segments,"
      "false_obstacles\n";
  for (const SweepRows& r : rows) {
    for (std::size_t v = 0; v < r.scores.size() && v < values.size(); ++v) {
      for (std::size_t m = 0; m < r.scores[v].size() && m < methods.size(); ++m) {
        const Score& s = r.scores[v][m];
        out += CsvField(r.world) + "," + sweep.key + "," + Number(values[v]) + "," +
               methods[m].key + "," + std::to_string(s.frames) + "," + std::to_string(s.strict.tp) +
               "," + std::to_string(s.strict.fp) + "," + std::to_string(s.strict.fn) + "," +
               Cell(s.strict.Precision(), 4) + "," + Cell(s.strict.Recall(), 4) + "," +
               Cell(s.strict.F1(), 4) + "," + std::to_string(s.band_excluded.fp) + "," +
               Cell(s.band_excluded.Precision(), 4) + "," + Cell(s.band_excluded.F1(), 4) + "," +
               std::to_string(s.objects_counted) + "," + std::to_string(s.objects_found) + "," +
               Cell(s.FoundRate(), 4) + "," + std::to_string(s.kept_segments) + "," +
               std::to_string(s.false_obstacles) + "\n";
      }
    }
  }
  return out;
}

std::string SweepMarkdown(const SweepSpec& sweep, const std::vector<Method>& methods,
                          const SweepScores& scores) {
  const std::vector<double> values = sweep.Values();
  const std::string unit = SettingUnit(sweep.key);
  std::string out = "| " + sweep.key + (unit.empty() ? "" : " [" + unit + "]");
  std::string rule = "| ---:";
  for (const Method& m : methods) {
    out += " | " + m.label + ": P (no band) / R / found / false";
    rule += " | ---:";
  }
  out += " |\n" + rule + " |\n";
  for (std::size_t v = 0; v < scores.size() && v < values.size(); ++v) {
    out += "| " + Number(values[v]);
    for (std::size_t m = 0; m < scores[v].size() && m < methods.size(); ++m) {
      const Score& s = scores[v][m];
      out += " | " + FormatRatio(s.band_excluded.Precision()) + " / " +
             FormatRatio(s.strict.Recall()) + " / " + Percent(s.FoundRate()) + " / " +
             std::to_string(s.false_obstacles);
    }
    out += " |\n";
  }
  return out;
}

std::string StatedExpectation(const std::string& description) {
  const std::size_t at = description.find("Expected:");
  if (at == std::string::npos) return "";
  std::string text;
  for (const char c : description.substr(at + 9)) {
    const char ch = c == '\n' ? ' ' : c;
    if (ch == ' ' && (text.empty() || text.back() == ' ')) continue;
    text += ch;
  }
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

std::string ObjectsMarkdown(const std::string& frame, const FrameEvaluation& e,
                            const std::vector<Method>& methods) {
  if (e.scores.empty() || e.scores[0].objects.empty()) return "";
  std::string out = "Objects in " + frame + " (share of each object's pixels detected; " +
                    "found when marked found, small objects are not counted):\n\n| object | " +
                    "obstacle | px";
  std::string rule = "| --- | --- | ---:";
  for (const Method& m : methods) {
    out += " | " + m.label;
    rule += " | ---:";
  }
  out += " |\n" + rule + " |\n";
  for (std::size_t k = 0; k < e.scores[0].objects.size(); ++k) {
    const ObjectOutcome& o = e.scores[0].objects[k];
    if (o.pixels == 0) continue;
    out += "| " +
           (o.name.empty() ? "#" + std::to_string(o.id) : o.name + " #" + std::to_string(o.id)) +
           " | " + (o.is_obstacle ? "yes" : "no") + " | " + std::to_string(o.pixels);
    for (std::size_t m = 0; m < methods.size(); ++m) {
      const ObjectOutcome& om = e.scores[m].objects[k];
      const double share = om.pixels > 0 ? double(om.detected) / om.pixels : 0.0;
      std::string cell = Percent(share);
      if (om.is_obstacle && !om.counted) cell += " (small)";
      if (om.found) cell += " found";
      out += " | " + cell;
    }
    out += " |\n";
  }
  return out + "\n";
}

std::string SettingsMarkdown(const od::io::DetectSettings& s, const std::string& config) {
  const od::DetectorConfig& d = s.detector;
  const od::RuleConfig& r = s.rules;
  std::ostringstream out;
  out << "Settings: " << (config.empty() ? "built-in defaults" : "`" + config + "`")
      << ". Detector: HT " << d.min_height_m << " m, Hmax " << d.max_height_m << " m, theta "
      << d.min_slope_rad * kRadToDeg << " deg, paper window scale " << d.window_scale
      << ". Rules: min_points " << r.min_points << ", min_volume " << r.min_volume_m3
      << " m^3, min_perimeter " << r.min_perimeter_m << " m, min_slope_mean "
      << r.min_slope_mean_rad * kRadToDeg << " deg, min_slope_max "
      << r.min_slope_max_rad * kRadToDeg << " deg, min_height_mean " << r.min_height_mean_m
      << " m, min_height_max " << r.min_height_max_m << " m, min_raised " << r.min_raised
      << " (0 disables a rule). Column baseline: min_blob_pixels " << s.min_blob_pixels << ".\n";
  return out.str();
}

std::vector<ClaimCheck> CheckWorld(const WorldScores& world, const std::vector<Method>& methods) {
  const auto find = [&](std::initializer_list<const char*> keys) -> const Score* {
    for (const char* key : keys) {
      for (std::size_t k = 0; k < methods.size() && k < world.per_method.size(); ++k) {
        if (methods[k].key == key) return &world.per_method[k];
      }
    }
    return nullptr;
  };
  const Score* cone = find({"cone_exact_rules"});
  const Score* cone_all = find({"cone_exact"});
  const Score* column = find({"column_rules", "column"});
  const Score* blobs = find({"column", "column_rules"});
  std::vector<ClaimCheck> checks;
  if (cone == nullptr) return checks;
  const auto add = [&](std::string claim, std::string measured, bool holds, bool general) {
    checks.push_back({std::move(claim), std::move(measured), holds, general});
  };
  const auto segs = [](const Score& s) {
    return "segments per object max " + std::to_string(s.segments_per_object_max) +
           ", obstacles per segment max " + std::to_string(s.objects_per_segment_max);
  };
  std::string stated = Lower(StatedExpectation(world.description));
  if (stated.empty()) stated = Lower(world.description);
  const auto says = [&](std::initializer_list<const char*> phrases) {
    for (const char* p : phrases) {
      if (stated.find(p) != std::string::npos) return true;
    }
    return false;
  };

  // The paper's claim on sideways faces, as the issue states it.
  if (Mentions(world, {"sideways-facing", "point sideways", "points sideways", "face sideways",
                       "faces sideways"}) &&
      column != nullptr) {
    add("steep faces that point sideways: the cone detector finds >= 90% of the obstacles, the "
        "column baseline at most half, with no more false obstacles",
        "cone " + Found(*cone) + ", " + std::to_string(cone->false_obstacles) + " false; column " +
            Found(*column) + ", " + std::to_string(column->false_obstacles) + " false",
        cone->FoundRate() >= 0.9 && column->FoundRate() <= 0.5 &&
            cone->false_obstacles <= column->false_obstacles,
        false);
  }
  // What the world's "Expected:" sentence states, phrase by phrase.
  if (says({"finds every", "finds all", "finds each", "finds both", "finds the ", "marks the ",
            "every obstacle is"})) {
    add("the cone detector finds every obstacle", Found(*cone),
        cone->objects_counted > 0 && cone->objects_found == cone->objects_counted, false);
  }
  if (const std::size_t at = stated.find("at least "); at != std::string::npos) {
    const double percent = std::atof(stated.c_str() + at + 9);
    if (percent > 0.0 && stated.find('%', at) != std::string::npos) {
      add("the cone detector finds at least " + Number(percent) + "% of the obstacles",
          Found(*cone), cone->FoundRate() >= percent / 100.0 - 1e-12, false);
    }
  }
  if (says({"at most half"}) && column != nullptr) {
    add("the column baseline finds at most half of the obstacles", Found(*column),
        column->FoundRate() <= 0.5, false);
  }
  if (says({"own segment", "one segment"})) {
    if (says({"about one segment"})) {
      // A claim made "about" the segmentation holds on average, not for every object.
      add("about one segment per obstacle found and one obstacle per segment (means <= 1.1)",
          "segments per object " + FormatRatio(cone->SegmentsPerObject()) +
              ", obstacles per segment " + FormatRatio(cone->ObjectsPerSegment()) + "; " +
              segs(*cone),
          cone->objects_found > 0 && cone->SegmentsPerObject() <= 1.1 &&
              cone->ObjectsPerSegment() <= 1.1,
          false);
    } else {
      add("every obstacle the cone detector finds is one segment, and no segment holds two",
          segs(*cone),
          cone->objects_found > 0 && cone->segments_per_object_max <= 1 &&
              cone->objects_per_segment_max <= 1,
          false);
    }
  }
  if (says({"finds nearly every", "finds nearly all", "finds almost every"})) {
    add("the cone detector finds nearly every obstacle (>= 90%)", Found(*cone),
        cone->FoundRate() >= 0.9, false);
  }
  if (says({"merges"}) && blobs != nullptr) {
    add("the column baseline's 2-D blobs merge objects that touch in the image",
        std::to_string(blobs->merged_segments) + " merged segments; " + segs(*blobs),
        blobs->merged_segments > 0, false);
  }
  if (says({"shares a segment", "share a segment"})) {
    add("objects that touch in 3-D share a cone segment",
        std::to_string(cone->merged_segments) + " segments hold two or more obstacles",
        cone->merged_segments > 0, false);
  }
  if (says({"none of the", "not marked"})) {
    add("no object that is not an obstacle is marked (none has " +
            std::string("half or more of its pixels in kept segments)"),
        std::to_string(cone->non_obstacles_marked) + " of " +
            std::to_string(cone->non_obstacles_counted) + " marked",
        cone->non_obstacles_marked == 0, false);
  }
  if (says({"no false obstacle", "neither reports a false", "no false"})) {
    const bool neither = says({"neither"}) && column != nullptr;
    add(neither ? "neither detector reports a false obstacle"
                : "the cone detector reports no false obstacle",
        "cone " + std::to_string(cone->false_obstacles) +
            (neither ? ", column " + std::to_string(column->false_obstacles) : std::string()),
        cone->false_obstacles == 0 && (!neither || column->false_obstacles == 0), false);
  }
  if (says({"no fewer false", "no more false"}) && column != nullptr) {
    add("the cone detector reports no more false obstacles than the column baseline",
        "cone " + std::to_string(cone->false_obstacles) + ", column " +
            std::to_string(column->false_obstacles),
        cone->false_obstacles <= column->false_obstacles, false);
  }
  if (says({"rules keep"}) && cone_all != nullptr) {
    add("the rules keep every obstacle found", Found(*cone_all) + " -> " + Found(*cone),
        cone->objects_found >= cone_all->objects_found, false);
  }
  if (says({"rules remove", "rules reject"}) && cone_all != nullptr) {
    add("the rules remove at least half of the false obstacles",
        std::to_string(cone_all->false_obstacles) + " -> " + std::to_string(cone->false_obstacles),
        2 * cone->false_obstacles <= cone_all->false_obstacles, false);
  }

  // What the method promises everywhere.
  add("the cone detector with rules finds >= 90% of the obstacles",
      Found(*cone) + ", " + std::to_string(cone->false_obstacles) + " false of " +
          std::to_string(cone->kept_segments) + " kept",
      cone->objects_counted > 0 && cone->FoundRate() >= 0.9, true);
  add("no cone segment holds two obstacles",
      "obstacles per segment: mean " + FormatRatio(cone->ObjectsPerSegment()) + ", max " +
          std::to_string(cone->objects_per_segment_max),
      cone->objects_per_segment_max <= 1, true);
  return checks;
}

std::vector<ClaimCheck> CheckGallery(const Score& cone_rules, const Score& cone_no_rules,
                                     const std::string& with, const std::string& without) {
  ClaimCheck c;
  c.claim = "across the gallery the rules remove most false obstacles while keeping recall";
  const double found_drop = cone_no_rules.FoundRate() - cone_rules.FoundRate();
  const double recall_drop = cone_no_rules.strict.Recall() - cone_rules.strict.Recall();
  c.measured = without + ": " + std::to_string(cone_no_rules.false_obstacles) +
               " false obstacles, found " + Found(cone_no_rules) + ", point recall " +
               FormatRatio(cone_no_rules.strict.Recall()) + "; " + with + ": " +
               std::to_string(cone_rules.false_obstacles) + " false, found " + Found(cone_rules) +
               ", point recall " + FormatRatio(cone_rules.strict.Recall());
  // With nothing to remove, the rules can only show that they keep recall.
  const bool removed = cone_no_rules.false_obstacles == 0
                           ? cone_rules.false_obstacles == 0
                           : 2 * cone_rules.false_obstacles < cone_no_rules.false_obstacles;
  c.holds = removed && !(found_drop > 0.05) && !(recall_drop > 0.05);
  return {c};
}

}  // namespace cairn::eval
