#include "tools/sim/simulator.h"

#include <cmath>

#include "tools/sim/office_plan.h"
#include "tools/sim/pgm_world.h"

namespace anchormap::sim {

Status Simulator::Create(const SimOptions& options, std::unique_ptr<Simulator>* simulator) {
  std::unique_ptr<Simulator> sim(new Simulator(options));
  if (options.world == "office") {
    OfficePlanOptions office = OfficeTilesForRobots(options.robots, options.office_robots_per_tile);
    office.seed = options.seed;
    sim->plan_ = BuildOfficePlan(office);
  } else if (Status status = LoadPgmWorld(options.world, options.world_resolution_m, &sim->plan_);
             !status.ok()) {
    return status;
  }
  sim->world_ = std::make_unique<World>(sim->plan_.walls);
  sim->planner_ = std::make_unique<RoutePlanner>(sim->plan_, options.planner);
  sim->destinations_ = std::make_unique<Destinations>(sim->plan_, *sim->planner_);
  sim->detector_ = std::make_unique<EncounterDetector>(options.encounters, options.robots);
  sim->laser_ = SimulatedLaser(options.laser);

  Rng world_rng(options.seed, 0, RngStream::kWorld);
  const std::vector<Eigen::Vector2d> starts =
      sim->destinations_->StartPositions(options.robots, world_rng);
  if (starts.size() != static_cast<size_t>(options.robots)) {
    return Status::Error("the world has no traversable room for " + std::to_string(options.robots) +
                         " robots (clearance " + std::to_string(options.planner.clearance_m) +
                         " m)");
  }
  for (int i = 0; i < options.robots; ++i) {
    const Pose2 start(starts[i].x(), starts[i].y(), world_rng.Uniform(-kPi, kPi));
    sim->robots_.emplace_back(i, start, options);
    sim->laser_rngs_.emplace_back(options.seed, static_cast<uint64_t>(i), RngStream::kLaser);
    sim->encounter_rngs_.emplace_back(options.seed, static_cast<uint64_t>(i),
                                      RngStream::kEncounter);
  }
  sim->step_us_ = std::llround(1e6 / options.odometry_rate_hz);
  sim->last_step_ =
      static_cast<int64_t>(std::floor(options.duration_s * 1e6 / sim->step_us_ + 1e-9));
  *simulator = std::move(sim);
  return Status::Ok();
}

SimFrame Simulator::Step() {
  SimFrame frame;
  const int64_t step = next_step_++;
  frame.utime = options_.start_utime + step * step_us_;
  if (step > 0) {
    const double dt_s = static_cast<double>(step_us_) * 1e-6;
    for (SimRobot& robot : robots_) robot.Advance(dt_s, *destinations_, *planner_);
  }
  if (step % options_.OdometryStepsPerScan() != 0) return frame;

  frame.has_scans = true;
  std::vector<Pose2> T_world_body;
  T_world_body.reserve(robots_.size());
  for (const SimRobot& robot : robots_) {
    frame.scans.push_back(
        laser_.Scan(*world_, robot.T_world_body(), frame.utime, laser_rngs_[robot.index()]));
    T_world_body.push_back(robot.T_world_body());
  }
  frame.encounters = detector_->Detect(frame.utime, *world_, T_world_body, encounter_rngs_);
  return frame;
}

}  // namespace anchormap::sim
