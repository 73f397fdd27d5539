#pragma once
// Seeded random numbers whose sequences are the same on every run and every platform that
// has IEEE doubles: std::mt19937_64 is fully specified by the standard, but the standard
// distributions are not, so the simulator draws through these functions instead.

#include <cstdint>
#include <random>

namespace anchormap::sim {

// Mixes a seed with stream identifiers (robot index, sensor kind) into an independent
// seed (splitmix64 finaliser), so that each robot and each sensor has its own stream and
// changing one option (say the beam count) does not change the other streams.
uint64_t StreamSeed(uint64_t seed, uint64_t robot_index, uint64_t stream);

// Stream identifiers for StreamSeed.
enum class RngStream : uint64_t {
  kRoute = 1,
  kOdometry = 2,
  kLaser = 3,
  kEncounter = 4,
  kWorld = 5,
  kOfficeLayout = 6,  // per office tile: its doors' places and furniture
};

class Rng {
 public:
  explicit Rng(uint64_t seed) : engine_(seed) {}
  Rng(uint64_t seed, uint64_t robot_index, RngStream stream)
      : engine_(StreamSeed(seed, robot_index, static_cast<uint64_t>(stream))) {}

  // Uniform in [0, 1), 53 random bits.
  double Uniform();
  // Uniform in [low, high).
  double Uniform(double low, double high) { return low + (high - low) * Uniform(); }
  // Uniform integer in [0, n); n > 0. Unbiased (rejection).
  uint64_t Index(uint64_t n);
  // Standard normal (Marsaglia's polar method; the spare value is kept).
  double Gaussian();
  double Gaussian(double mean, double stddev) { return mean + stddev * Gaussian(); }
  bool Bernoulli(double probability) { return Uniform() < probability; }

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

}  // namespace anchormap::sim
