// cairn map's command line: its options and help (the run itself: map.cpp).
#include <CLI/CLI.hpp>
#include <memory>

#include "map_run.hpp"
#include "subcommands.hpp"

namespace cairn::apps {

Subcommand AddMapCommand(CLI::App& parent) {
  auto options = std::make_shared<MapOptions>();
  CLI::App* app = parent.add_subcommand(
      "map",
      "Fuse a whole sequence into an OctoMap and a 2.5-D cost grid: detect obstacles in every "
      "frame, place it by odometry (or given poses), write the map files and a summary");
  // One input, with the options that go with it.
  CLI::Option_group* input = app->add_option_group(
      "input", "one of --rawlog FILE, --kitti DIR, --frames DIR (with --poses FILE.tum)");
  input
      ->add_option("--rawlog", options->rawlog,
                   "MRPT rawlog with range frames and odometry (IMU used when present)")
      ->type_name("FILE");
  app->add_option("--label", options->label, "with --rawlog: the range sensor's label")
      ->type_name("L");
  input
      ->add_option("--kitti", options->kitti,
                   "KITTI odometry sequence folder (velodyne/, calib.txt, times.txt, poses.txt), "
                   "or the data set's root with --sequence")
      ->type_name("DIR");
  app->add_option("--sequence", options->sequence, "with --kitti: DIR/sequences/NN")
      ->type_name("NN");
  app->add_option("--range", options->range, "with --kitti: scans A:B (inclusive)")
      ->type_name("A:B");
  app->add_option("--lidar", options->lidar,
                  "with --kitti: sensor preset (HDL-64E, VLP-16, VLP-32C, OS1-64; any case)")
      ->capture_default_str();
  CLI::Option* frames =
      input
          ->add_option(
              "--frames", options->frames,
              "folder of 16-bit depth PNGs, or of stereo pairs in left/ and right/ (named by "
              "stamp, or in pose order)")
          ->type_name("DIR");
  input->require_option(1);
  CLI::Option* poses =
      app->add_option("--poses", options->poses,
                      "with --frames: TUM file of the camera's (the left camera's) poses (optical "
                      "frame, z-up world)")
          ->type_name("FILE.tum");
  frames->needs(poses);
  app->add_option("--intrinsics", options->intrinsics,
                  "with --frames: camera YAML (default DIR/intrinsics.yaml)")
      ->type_name("FILE");
  app->add_option("--stereo-calib", options->stereo_calib,
                  "with --frames of stereo pairs (DIR/left/, DIR/right/): the rig's "
                  "calibration, any format of cairn detect --stereo-calib (default "
                  "DIR/stereo.yaml)")
      ->type_name("FILE");
  app->add_option("--config", options->config,
                  "settings YAML: detector, rules, stereo, map, tilt and frames sections "
                  "(config/default.yaml documents them)")
      ->type_name("FILE");
  app->add_option("--out", options->out, "output folder (created when missing)")
      ->required()
      ->type_name("DIR");
  CLI::Option* window =
      app->add_option("--window", options->window_m,
                      "online: a rolling window this wide follows the robot (map.window_size)")
          ->check(CLI::NonNegativeNumber)
          ->type_name("METRES");
  app->add_flag("--offline", options->offline, "unbounded map of the whole sequence")
      ->excludes(window);
  CLI::Option* refine = app->add_flag("--refine-tilt", options->refine_tilt,
                                      "refine each frame's roll, pitch and height with Ceres "
                                      "against the terrain fused so far (tilt.refine)");
  CLI::Option* no_refine =
      app->add_flag("--no-refine-tilt", options->no_refine_tilt, "do not (overrides the config)")
          ->excludes(refine);
  app->add_option("--tilt", options->tilt,
                  "how each frame's roll, pitch and height are found (tilt.mode): prior (the "
                  "odometry pose), refine_to_map (Ceres against the terrain fused so far), "
                  "gravity (Ceres over a window: accelerometer, gyro, trunks, poles and walls)")
      ->check(CLI::IsMember({"prior", "refine_to_map", "gravity"}))
      ->excludes(refine)
      ->excludes(no_refine)
      ->type_name("MODE");
  app->add_flag("--smooth", options->smooth,
                "with --tilt gravity (or tilt.mode gravity): once the input is read, every frame "
                "posed again by the smoother (the whole run solved together: the mount and biases "
                "learned at the first trunks or turn apply from the first frame on) and the map "
                "fused again at those poses, reading the input twice (offline map building; "
                "tilt.smooth in --config)");
  app->add_flag("--strict", options->strict,
                "a frame that cannot be used (missing, truncated, no valid points, a pose that "
                "jumps) is an error, not a frame skipped and counted");
  app->add_option("--max-frames", options->max_frames, "stop after N frames")
      ->check(CLI::PositiveNumber)
      ->type_name("N");
  app->add_option("--checkpoint-every", options->checkpoint_every,
                  "save the map and the run's state to DIR/map.checkpoint every N frames (and "
                  "when interrupted), for --resume; 0: only when interrupted")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app->add_flag("--resume", options->resume,
                "continue an interrupted run from DIR/map.checkpoint (same input, same --config)");
  app->add_option("--progress-every", options->progress_every,
                  "when stderr is not a terminal: a progress line every N frames")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app->add_option("--truth-poses", options->truth_poses,
                  "TUM file of the sensor's true poses (e.g. poses_sensor.tum of `cairn synth "
                  "--drive`): the fused poses' tilt and height errors in the summary")
      ->type_name("FILE.tum");
#ifdef CAIRN_HAVE_SYNTH
  app->add_option("--truth", options->truth,
                  "world YAML of a synthetic sequence: score the obstacles and the elevation")
      ->type_name("WORLD.yaml");
#endif
  app->footer(
      "Writes into DIR: map.bt, map.ot, obstacles.ot (OctoMap), cost.yaml + cost.pgm "
      "(map_server), cost.png, overlay.png, elevation.tiff + elevation.yaml, obstacles.json, "
      "poses.tum, frames.csv, summary.json, summary.txt. Frames that cannot be used are named "
      "on stderr and counted in the summary by reason. Exit 1 on bad input (nothing written; a "
      "checkpoint of an earlier interruption stays), 130 when interrupted (the map so far kept "
      "in DIR/map.checkpoint: run again with --resume).");
  return {app, [options] { return RunMap(*options); }};
}

}  // namespace cairn::apps
