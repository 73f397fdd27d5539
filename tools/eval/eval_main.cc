// anchormap-eval: accuracy of a merged map (see docs/TOOLS-DATA.md).
//   anchormap-eval --map OUT.lcmlog --truth SIM.lcmlog [--json]
//       ATE / RPE per trajectory and for the merged map against <R>_GROUND_TRUTH or
//       <R>_REFERENCE poses, matched by keyframe time.
//   anchormap-eval --relations FILE.relations --map OUT.lcmlog [--robot R1] [--json]
//       the relations metric of Kümmerle et al. 2009.
// --map and --truth also accept TUM trajectory files. Exit status: 0 done, 1 bad input or
// nothing could be evaluated, 2 bad command line.

#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <string>

#include <boost/program_options.hpp>

#include "common/bus/authenticator.h"
#include "common/bus/channels.h"
#include "tools/eval/clock_shift.h"
#include "tools/eval/eval_inputs.h"
#include "tools/eval/eval_report.h"
#include "tools/eval/map_evaluation.h"
#include "tools/eval/relations.h"

namespace po = boost::program_options;
using namespace anchormap;

namespace {

const char* kUsage =
    "Usage: anchormap-eval --map OUT.lcmlog --truth SIM.lcmlog [--json]\n"
    "       anchormap-eval --relations FILE.relations --map OUT.lcmlog [--robot R1]\n"
    "                      [--odometry RAW.lcmlog] [--json]\n"
    "The estimate is the last complete merged map of a server output log, or a\n"
    "TUM trajectory file. The reference is every <R>_GROUND_TRUTH or <R>_REFERENCE channel of a\n"
    "raw log (simulator, CARMEN importer), or a TUM trajectory file.\n";

int Fail(const std::string& message, int code) {
  std::cerr << "anchormap-eval: " << message << "\n";
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  std::string map_path, truth_path, relations_path, robot, odometry_path;
  std::string map_channel = channels::kMergedMap;
  std::string map_header_channel = channels::kMapHeader;
  std::string map_chunks_channel = channels::kMapChunks;
  RelationsOptions relations_options;
  bool json = false;
  std::string relation_errors_path, estimate_path, key_file;
  po::options_description visible("Options");
  visible.add_options()("help,h", "print this help and exit")(
      "map", po::value(&map_path), "the estimate: server output LCM log or TUM file (required)")(
      "truth", po::value(&truth_path), "reference poses: raw LCM log or TUM file (ATE / RPE)")(
      "relations", po::value(&relations_path), "a .relations file (relations metric)")(
      "robot", po::value(&robot),
      "relations: evaluate this robot's trajectories only (default: all); also the robot name "
      "of a TUM file (default R1)")(
      "max-time-gap-s",
      po::value(&relations_options.max_time_gap_s)
          ->default_value(relations_options.max_time_gap_s, "0.05"),
      "an estimated pose and a reference pose or relation time match when this close in time")(
      "map-channel", po::value(&map_channel)->default_value(map_channel),
      "channel of the merged map in output logs of servers before the chunks")(
      "map-header-channel", po::value(&map_header_channel)->default_value(map_header_channel),
      "channel of the merged map's header in the server's output log")(
      "map-chunks-channel", po::value(&map_chunks_channel)->default_value(map_chunks_channel),
      "channel of the merged map's chunks in the server's output log")(
      "key-file", po::value(&key_file), kServerOutputKeyFileHelp)(
      "odometry", po::value(&odometry_path),
      "relations: the raw log (<R>_ODOMETRY); poses at the relations' times are then the "
      "nearest keyframe plus the odometry motion since it, instead of keyframes only; its "
      "<R>_CLOCK_SHIFT messages (anchormap-import-carmen --simultaneous) map the robots' times "
      "back to the relations' clock")("json", po::bool_switch(&json),
                                      "print one JSON object instead of a table")(
      "relation-errors", po::value(&relation_errors_path),
      "relations: also write each evaluated relation's errors to this file, one a line "
      "\"t1 t2 distance_m translation_error_m rotation_error_rad\" (where the error comes from)")(
      "write-estimate", po::value(&estimate_path),
      "relations: also write the poses the relations were evaluated on, one a line \"t x y "
      "theta frame\" (keyframes, or keyframes and completed poses with --odometry)");
  po::variables_map vm;
  try {
    po::store(po::command_line_parser(argc, argv).options(visible).run(), vm);
    po::notify(vm);
  } catch (const std::exception& e) {
    return Fail(std::string(e.what()) + " (see --help)", 2);
  }
  if (vm.count("help")) {
    std::cout << kUsage << "\n" << visible;
    return 0;
  }
  if (map_path.empty()) return Fail("--map is required (see --help)", 2);
  if (truth_path.empty() == relations_path.empty()) {
    return Fail("give exactly one of --truth and --relations (see --help)", 2);
  }
  if (Status s = relations_options.Validate(); !s.ok())
    return Fail("bad option: " + s.message(), 2);
  const std::string tum_robot = robot.empty() ? "R1" : robot;

  std::optional<Authenticator> authenticator;
  if (!key_file.empty()) {
    AuthenticatorOptions checking;
    checking.sender = "eval";  // (it never signs)
    Result<Authenticator> loaded = LoadAuthenticator(key_file, checking);
    if (!loaded.ok()) return Fail(loaded.status().message(), 1);
    authenticator.emplace(std::move(*loaded));
  }
  MapEstimate estimate;
  if (Status s = ReadMapEstimate(map_path, map_channel, tum_robot, &estimate,
                                 authenticator ? &*authenticator : nullptr, map_header_channel,
                                 map_chunks_channel);
      !s.ok()) {
    return Fail(s.message() + (authenticator ? "" : " (a signed log needs --key-file)"), 1);
  }
  if (estimate.unauthenticated > 0) {
    std::cerr << "anchormap-eval: warning: " << estimate.unauthenticated
              << " merged maps refused by the key check (unsigned, unknown key or forged)\n";
  }
  if (estimate.undecodable > 0 || estimate.invalid_poses > 0) {
    std::cerr << "anchormap-eval: warning: " << estimate.undecodable
              << " undecodable merged maps and " << estimate.invalid_poses
              << " non-finite poses skipped\n";
  }

  if (!truth_path.empty()) {
    ReferenceSet references;
    if (Status s = ReadReferences(truth_path, tum_robot, &references); !s.ok()) {
      return Fail(s.message(), 1);
    }
    AteReport report =
        EvaluateAgainstReferences(estimate, references, relations_options.max_time_gap_s);
    report.map_path = map_path;
    report.truth_path = truth_path;
    std::cout << (json ? FormatAteJson(report) : FormatAteTable(report));
    int64_t matched = 0;
    for (const TrajectoryReport& t : report.trajectories) matched += t.error.matched;
    if (matched == 0) return Fail("no estimated pose matched a reference pose in time", 1);
    return 0;
  }

  std::vector<Relation> relations;
  if (Status s = ReadRelationsFile(relations_path, &relations); !s.ok()) {
    return Fail(s.message(), 1);
  }
  std::map<std::string, StampedTrajectory> odometry_by_robot;
  OdometryCompletion completion;
  int completed_trajectories = 0;
  int64_t time_repaired_ends = 0;
  if (!odometry_path.empty()) {
    int64_t undecodable = 0;
    if (Status s = ReadPoseChannels(odometry_path, channels::kOdometrySuffix, &odometry_by_robot,
                                    &undecodable);
        !s.ok()) {
      return Fail(s.message(), 1);
    }
    if (odometry_by_robot.empty()) return Fail(odometry_path + ": no <R>_ODOMETRY channel", 1);
    std::map<std::string, int64_t> shift_by_robot;
    if (Status s = ReadClockShifts(odometry_path, &shift_by_robot); !s.ok()) {
      return Fail(s.message(), 1);
    }
    ShiftToLogClock(shift_by_robot, &estimate, &odometry_by_robot);
    std::map<int64_t, int64_t> repaired_by_stamp;
    if (Status s = ReadTimeRepairs(odometry_path, shift_by_robot, &repaired_by_stamp); !s.ok()) {
      return Fail(s.message(), 1);
    }
    time_repaired_ends = ApplyTimeRepairs(repaired_by_stamp, &relations);
    completion.odometry_by_robot = &odometry_by_robot;
    completion.relations = &relations;
    completion.max_time_gap_s = relations_options.max_time_gap_s;
    completion.completed_trajectories = &completed_trajectories;
  }
  RelationsEstimate relations_estimate;
  if (Status s = BuildRelationsEstimate(estimate, robot, completion, &relations_estimate);
      !s.ok()) {
    return Fail(map_path + ": " + s.message(), 1);
  }
  RelationsReport report;
  report.relations_path = relations_path;
  report.map_path = map_path;
  report.robot = robot;
  report.map_update = estimate.update;
  report.estimate_poses = static_cast<int64_t>(relations_estimate.poses.size());
  report.max_time_gap_s = relations_options.max_time_gap_s;
  if (!estimate_path.empty()) {
    std::ofstream out(estimate_path);
    out.precision(10);
    const StampedTrajectory& poses = relations_estimate.poses;
    for (size_t i = 0; i < poses.size(); ++i) {
      out << 1e-6 * static_cast<double>(poses[i].utime) << ' ' << poses[i].pose.x() << ' '
          << poses[i].pose.y() << ' ' << poses[i].pose.theta() << ' '
          << (relations_estimate.frame_ids.empty() ? 0 : relations_estimate.frame_ids[i]) << '\n';
    }
    if (!out) return Fail("cannot write " + estimate_path, 1);
  }
  std::vector<RelationError> per_relation;
  report.result = EvaluateRelations(relations, relations_estimate, relations_options,
                                    relation_errors_path.empty() ? nullptr : &per_relation);
  if (!relation_errors_path.empty()) {
    std::ofstream out(relation_errors_path);
    out.precision(10);
    for (const RelationError& e : per_relation) {
      out << e.t1_s << ' ' << e.t2_s << ' ' << e.distance_m << ' ' << e.translation_m << ' '
          << e.rotation_rad << '\n';
    }
    if (!out) return Fail("cannot write " + relation_errors_path, 1);
  }
  report.odometry_path = odometry_path;
  report.completed_trajectories = completed_trajectories;
  report.time_repaired_ends = time_repaired_ends;
  std::cout << (json ? FormatRelationsJson(report) : FormatRelationsTable(report));
  if (report.result.evaluated == 0) return Fail("no relation could be evaluated", 1);
  return 0;
}
