#pragma once
// The merged map as a pose graph for g2o-reading tools: one vertex per keyframe (ids
// numbered through the trajectories in message order), an edge between consecutive
// keyframes of each trajectory and one per encounter link; each edge's measurement is the
// relative pose of the current estimates, with identity information (the server's output
// carries no measurement covariances). Written with common/io/graph_file.h.

#include <cstdint>
#include <vector>

#include "common/io/graph_file.h"
#include "tools/render/server_output.h"

namespace anchormap::render {

// `skipped_links` (optional) counts encounter links whose keyframes are unknown.
PoseGraph BuildMergedGraph(const MergedMap& map, int* skipped_links = nullptr);

}  // namespace anchormap::render
