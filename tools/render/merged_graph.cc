#include "tools/render/merged_graph.h"

#include <map>

namespace anchormap::render {

PoseGraph BuildMergedGraph(const MergedMap& map, int* skipped_links) {
  PoseGraph graph;
  std::map<TrajectoryKey, int64_t> first_id;  // trajectory -> vertex id of its keyframe 0
  int64_t next_id = 0;
  for (const TrajectoryView& t : map.trajectories) {
    first_id[t.key] = next_id;
    for (size_t i = 0; i < t.poses.size(); ++i) {
      graph.vertices.push_back({next_id + static_cast<int64_t>(i), t.poses[i]});
      if (i > 0) {
        graph.edges.push_back({next_id + static_cast<int64_t>(i) - 1,
                               next_id + static_cast<int64_t>(i),
                               Between(t.poses[i - 1], t.poses[i]), Eigen::Matrix3d::Identity()});
      }
    }
    next_id += static_cast<int64_t>(t.poses.size());
  }
  int skipped = 0;
  for (const EncounterLink& link : map.encounters) {
    const Pose2* a = map.FindPose(link.a, link.index_a);
    const Pose2* b = map.FindPose(link.b, link.index_b);
    if (!a || !b) {
      ++skipped;
      continue;
    }
    graph.edges.push_back({first_id[link.a] + link.index_a, first_id[link.b] + link.index_b,
                           Between(*a, *b), Eigen::Matrix3d::Identity()});
  }
  if (skipped_links) *skipped_links = skipped;
  return graph;
}

}  // namespace anchormap::render
