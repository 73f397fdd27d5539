#pragma once
// Keyframes of a robot driving straight for the server's tests: keyframe `seq` is 1 m
// further along the trajectory's x axis, one second later (keyframe 0 at `first_utime`), with
// `num_rays` laser rays (0.01 rad apart, starting straight ahead) that each hit something 2 m
// away.

#include <cstdint>
#include <string>

#include "common/types/keyframe.h"

namespace anchormap::testing {

Keyframe StraightKeyframe(const std::string& robot, int64_t trajectory_id, int32_t seq,
                          int num_rays = 1, int64_t first_utime = 1'000'000);

}  // namespace anchormap::testing
