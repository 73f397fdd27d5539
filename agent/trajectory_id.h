#pragma once
// A new trajectory id for each agent session, drawn from the operating system's random
// source (std::random_device: getrandom() on Linux), so that agents started together, or
// a robot restarted, never share one (issue 13: wall-clock microseconds collided in 36 of
// 400 trials of three agents started together). 63 random bits: positive, never 0 (0 asks
// for a draw); two draws collide with probability 2^-63.

#include <cstdint>

namespace anchormap {

int64_t DrawTrajectoryId();

}  // namespace anchormap
