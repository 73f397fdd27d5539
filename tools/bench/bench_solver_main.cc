// anchormap-bench-solver: replays a 2D pose graph into the smoother, as one robot or cut
// into N robots (docs/METHOD.md section 9), and prints timing, accuracy and convergence figures.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <exception>
#include <string>
#include <vector>

#include "common/io/graph_file.h"
#include "common/solver/smoother.h"
#include "common/util/retain_freed_memory.h"
#include "tests/testing/graph_replay.h"

namespace anchormap {
namespace {

constexpr const char* kUsage = R"(usage: anchormap-bench-solver GRAPH [options]

Replays GRAPH (g2o or TORO) into the incremental smoother and prints figures.

  --mode incremental|batch    incremental: add pose by pose, solve after every step
                              (default); batch: add everything, one batch solve
  --robots N                  cut the trajectory into N robots (default 1)
  --server-mode               start from the mapping server's options (ServerModeOptions:
                              relinearise at 0.01, partial merges, no clock batch steps);
                              flags after it change them
  --partial-merges true|false merge anchored groups by a partial step (relative formulation)
  --formulation F             relative | global | global-moved (default relative)
  --batch-every K             batch step every K updates (default 100, 0 = never)
  --method gn|dogleg          nonlinear method of batch steps (default gn)
  --threshold X               back-substitution threshold (default 0 = exact)
  --relinearize X             batch step when an estimate moved X from its linearisation
                              point (default 0 = off, pure iSAM)
  --relinearize-skip K        look at drift every K updates (default 1)
  --full-relinearization      on drift, run a full batch step (the old way) instead of the
                              partial relinearisation
  --correct TOL               after every update, move the estimate toward the nonlinear
                              optimum (R as preconditioner) until the predicted chi2
                              decrease is below TOL x chi2 (default 0 = off)
  --correct-iterations K      at most K correction steps per update (default 5)
  --relinearize-on-stall      look at drift only when the correction did not converge
  --correct-cg M              correction steps by conjugate gradients (R^T R as the
                              preconditioner); more than M iterations in an update is a stall
  --correct-skip F            with --correct-cg: leave an update uncorrected while the
                              predicted decrease stays below F x TOL x chi2 (default 5)
  --correct-local H           with --correct-cg: correct an update first on the variables
                              within H factor hops of its new factors (default 0 = off)
  --check-every K             untimed: every K steps, the batch optimum of the edges so far
                              (started from the current estimate); prints the worst relative
                              chi2 excess of the step's estimate over it (0 = off)
  --fill-factor F             batch when nnz(R) grows by F since the last one (default 4,
                              --server-mode 1.5; 0 = off)
  --givens-work-budget F      an update whose Givens rotations would take more than F work
                              units per non-zero of R after its last ordering is a batch
                              step instead (default 4; 0 = off)
  --convergence-decrease F    batch steps also stop when the chi2 decrease their step
                              predicts is below F x chi2 (default 0 = off)
  --converge-batches          periodic batch steps iterate to convergence (the thesis'
                              protocol for iterations_to_1e-4) instead of relinearising once
  --break-chain ID            drop the odometry edge (ID-1, ID): pose ID starts a new
                              trajectory in its own frame (repeatable)
  --no-reference              skip the reference batch optimum (its chi2 and the difference)
  --json                      print one JSON object instead of text
  --help                      this text
)";

struct Flags {
  std::string graph;
  bool incremental = true;
  int robots = 1;
  SmootherOptions smoother;
  std::vector<int64_t> break_chain;  // poses whose odometry edge is dropped
  int check_every = 0;
  bool reference = true;
  bool json = false;
};

[[noreturn]] void Fail(const std::string& message) {
  std::fprintf(stderr, "anchormap-bench-solver: %s\n(see --help)\n", message.c_str());
  std::exit(2);
}

double ParseNumber(const std::string& flag, const char* text) {
  char* end = nullptr;
  const double value = std::strtod(text, &end);
  if (end == text || *end != '\0') Fail(flag + " expects a number, got '" + text + "'");
  return value;
}

Flags ParseFlags(int argc, char** argv) {
  Flags flags;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) Fail(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    } else if (arg == "--mode") {
      const std::string mode = value();
      if (mode != "incremental" && mode != "batch") Fail("--mode must be incremental or batch");
      flags.incremental = mode == "incremental";
    } else if (arg == "--robots") {
      flags.robots = static_cast<int>(ParseNumber(arg, value()));
      if (flags.robots < 1) Fail("--robots must be >= 1");
    } else if (arg == "--formulation") {
      const std::string text = value();
      auto formulation = ParseFormulation(text);
      if (!formulation)
        Fail("--formulation must be relative, global or global-moved, got '" + text + "'");
      flags.smoother.formulation = *formulation;
    } else if (arg == "--server-mode") {
      const SmootherOptions server = ServerModeOptions();
      flags.smoother.batch_every_updates = server.batch_every_updates;
      flags.smoother.relinearize_threshold = server.relinearize_threshold;
      flags.smoother.partial_merges = server.partial_merges;
      flags.smoother.batch_when_fill_grows = server.batch_when_fill_grows;
      flags.smoother.relinearize_skip = server.relinearize_skip;
      flags.smoother.latest_poses_last = server.latest_poses_last;
    } else if (arg == "--partial-merges") {
      const std::string text = value();
      if (text != "true" && text != "false") Fail("--partial-merges must be true or false");
      flags.smoother.partial_merges = text == "true";
    } else if (arg == "--batch-every") {
      flags.smoother.batch_every_updates = static_cast<int>(ParseNumber(arg, value()));
    } else if (arg == "--method") {
      const std::string method = value();
      if (method != "gn" && method != "dogleg") Fail("--method must be gn or dogleg");
      flags.smoother.method =
          method == "gn" ? NonlinearMethod::kGaussNewton : NonlinearMethod::kDogLeg;
    } else if (arg == "--threshold") {
      flags.smoother.backsubstitution_threshold = ParseNumber(arg, value());
    } else if (arg == "--relinearize") {
      flags.smoother.relinearize_threshold = ParseNumber(arg, value());
    } else if (arg == "--convergence-decrease") {
      flags.smoother.convergence_decrease = ParseNumber(arg, value());
    } else if (arg == "--fill-factor") {
      flags.smoother.batch_when_fill_grows = ParseNumber(arg, value());
    } else if (arg == "--givens-work-budget") {
      flags.smoother.givens_work_budget = ParseNumber(arg, value());
    } else if (arg == "--relinearize-skip") {
      flags.smoother.relinearize_skip = static_cast<int>(ParseNumber(arg, value()));
    } else if (arg == "--correct") {
      flags.smoother.correction_tolerance = ParseNumber(arg, value());
    } else if (arg == "--correct-cg") {
      flags.smoother.correction_cg_iterations = static_cast<int>(ParseNumber(arg, value()));
    } else if (arg == "--correct-skip") {
      flags.smoother.correction_skip_factor = ParseNumber(arg, value());
    } else if (arg == "--correct-local") {
      flags.smoother.correction_local_hops = static_cast<int>(ParseNumber(arg, value()));
    } else if (arg == "--correct-iterations") {
      flags.smoother.correction_iterations = static_cast<int>(ParseNumber(arg, value()));
    } else if (arg == "--relinearize-on-stall") {
      flags.smoother.relinearize_when_correction_stalls = true;
    } else if (arg == "--full-relinearization") {
      flags.smoother.partial_relinearization = false;
    } else if (arg == "--check-every") {
      flags.check_every = static_cast<int>(ParseNumber(arg, value()));
      if (flags.check_every < 0) Fail("--check-every must be >= 0");
    } else if (arg == "--converge-batches") {
      flags.smoother.converge_periodic_batches = true;
    } else if (arg == "--break-chain") {
      const double id = ParseNumber(arg, value());
      if (!(id >= 1) || id != static_cast<double>(static_cast<int64_t>(id))) {
        Fail("--break-chain expects a pose id >= 1");
      }
      flags.break_chain.push_back(static_cast<int64_t>(id));
    } else if (arg == "--no-reference") {
      flags.reference = false;
    } else if (arg == "--json") {
      flags.json = true;
    } else if (!arg.empty() && arg[0] == '-') {
      Fail("unknown flag '" + arg + "'");
    } else if (flags.graph.empty()) {
      flags.graph = arg;
    } else {
      Fail("more than one graph file given");
    }
  }
  if (flags.graph.empty()) Fail("no graph file given");
  if (Status valid = flags.smoother.Validate(); !valid.ok()) Fail(valid.message());
  return flags;
}

double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(q * (values.size() - 1) + 0.5));
  return values[k];
}

int Run(const Flags& flags) {
  PoseGraph graph;  // edited by --break-chain
  if (Status s = ReadPoseGraph(flags.graph, &graph); !s.ok()) {
    std::fprintf(stderr, "anchormap-bench-solver: %s\n", s.message().c_str());
    return 1;
  }
  if (!flags.break_chain.empty()) {
    std::vector<GraphEdge> kept;
    for (const GraphEdge& e : graph.edges) {
      const bool dropped = e.to == e.from + 1 &&
                           std::find(flags.break_chain.begin(), flags.break_chain.end(), e.to) !=
                               flags.break_chain.end();
      if (!dropped) kept.push_back(e);
    }
    graph.edges.swap(kept);
  }
  const GraphReplay replay(graph, flags.robots);
  if (!replay.status().ok()) {
    std::fprintf(stderr, "anchormap-bench-solver: %s: %s\n", flags.graph.c_str(),
                 replay.status().message().c_str());
    return 1;
  }
  Smoother smoother(flags.smoother);
  std::vector<double> step_ms;
  const auto start = std::chrono::steady_clock::now();
  // CPU seconds of this process (what the reference's total_cpu_s measures too): on a
  // loaded machine the wall clock counts the other processes' share.
  const std::clock_t cpu_start = std::clock();
  int failures = 0;
  std::string first_failure;
  auto check = [&](const Status& s) {
    if (!s.ok() && failures++ == 0) first_failure = s.message();
  };
  // --check-every: the batch optimum of steps 0..k, from the current estimate; untimed.
  double worst_excess = 0.0, excess_sum = 0.0;
  int checks = 0, worst_step = -1;
  double checking_s = 0.0;
  double checking_cpu_s = 0.0;
  auto check_step = [&](int k) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::clock_t cpu_t0 = std::clock();
    SmootherOptions options = flags.smoother;
    options.batch_every_updates = 0;
    Smoother optimum(options);
    // Started from this run's estimate: the optimum nearest to it, not another minimum.
    for (int j = 0; j <= k; ++j) check(replay.AddStep(j, &optimum, false, &smoother));
    check(optimum.BatchOptimize(1e-6).status);
    const double reference = optimum.Chi2();
    const double excess = (smoother.Chi2() - reference) / std::max(reference, 1e-12);
    if (excess > worst_excess) {
      worst_excess = excess;
      worst_step = k;
    }
    excess_sum += excess;
    ++checks;
    checking_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    checking_cpu_s += static_cast<double>(std::clock() - cpu_t0) / CLOCKS_PER_SEC;
  };
  if (flags.incremental) {
    step_ms.reserve(replay.num_steps());
    for (int k = 0; k < replay.num_steps(); ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      check(replay.AddStep(k, &smoother));
      check(smoother.Update().status);
      step_ms.push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      if (flags.check_every > 0 &&
          ((k + 1) % flags.check_every == 0 || k + 1 == replay.num_steps())) {
        check_step(k);
      }
    }
  } else {
    check(replay.AddAll(&smoother));
    check(smoother.BatchOptimize().status);
  }
  const double total_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() - checking_s;
  const double total_cpu_s =
      static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC - checking_cpu_s;
  const double chi2 = smoother.Chi2();
  const SmootherStats stats = smoother.stats();  // before the (untimed) final batch step
  const CorrectionWork work = smoother.correction_work();
  const double nnz_per_column =
      static_cast<double>(stats.nnz_r) / std::max<int64_t>(1, 3 * stats.variables);

  // Untimed: a final batch step of this run, and the batch optimum of the same edges.
  double chi2_final_batch = chi2;
  if (flags.incremental) {
    check(smoother.BatchOptimize().status);
    chi2_final_batch = smoother.Chi2();
  }
  double chi2_reference = -1.0;
  if (flags.reference) {
    SmootherOptions options = flags.smoother;
    options.batch_every_updates = 0;
    Smoother reference(options);
    check(replay.AddAll(&reference));
    check(reference.BatchOptimize().status);
    chi2_reference = reference.Chi2();
  }
  const double relative_difference =
      chi2_reference > 0 ? (chi2_final_batch - chi2_reference) / chi2_reference : 0.0;

  const char* mode = flags.incremental ? "incremental" : "batch";
  const char* method = flags.smoother.method == NonlinearMethod::kDogLeg ? "dogleg" : "gn";
  if (flags.json) {
    std::printf(
        "{\"graph\": \"%s\", \"mode\": \"%s\", \"formulation\": \"%s\", \"method\": \"%s\", "
        "\"poses\": %d, \"factors\": %lld, \"edges\": %d, \"encounters\": %d, \"robots\": %d, "
        "\"trajectories\": %d, \"chain_breaks\": %d, "
        "\"batch_every\": %d, \"threshold\": %g, \"total_s\": %.4f, \"total_cpu_s\": %.4f, "
        "\"step_median_ms\": %.4f, "
        "\"step_p99_ms\": %.4f, \"step_max_ms\": %.4f, \"batch_s\": %.4f, "
        "\"incremental_s\": %.4f, \"batch_steps\": %lld, "
        "\"batch_steps_on_clock\": %lld, \"batch_steps_on_fill\": %lld, "
        "\"batch_steps_on_merge\": %lld, \"batch_steps_on_drift\": %lld, "
        "\"batch_iterations\": %lld, \"chi2\": %.6f, "
        "\"chi2_after_final_batch\": %.6f, \"chi2_batch_optimum\": %.6f, "
        "\"chi2_relative_difference\": %.3e, \"nnz_per_column\": %.3f, "
        "\"iterations_to_1e-4\": %lld, \"rows_backsubstituted_per_step\": %.1f, "
        "\"givens_block_rows\": %lld, \"givens_block_columns\": %lld, "
        "\"partial_relinearizations\": %lld, \"partial_s\": %.4f, "
        "\"relinearized_variables\": %lld, \"rows_reeliminated\": %lld, "
        "\"rows_before_closure\": %lld, \"rows_in_tails\": %lld, "
        "\"partial_merges\": %lld, \"correction_steps\": %lld, "
        "\"correction_stalls\": %lld, \"correction_skips\": %lld, \"correction_s\": %.4f, "
        "\"gradient_passes\": %lld, \"factors_linearized_by_passes\": %lld, "
        "\"checked_steps\": %d, \"worst_step_chi2_excess\": %.3e, "
        "\"failures\": %d, \"first_failure\": \"%s\"}\n",
        flags.graph.c_str(), mode, ToString(flags.smoother.formulation), method, replay.num_poses(),
        static_cast<long long>(stats.factors), replay.num_edges(), replay.num_encounters(),
        replay.robots(), replay.num_trajectories(), replay.num_chain_breaks(),
        flags.smoother.batch_every_updates, flags.smoother.backsubstitution_threshold, total_s,
        total_cpu_s, Percentile(step_ms, 0.5), Percentile(step_ms, 0.99), Percentile(step_ms, 1.0),
        stats.batch_seconds, stats.incremental_seconds, static_cast<long long>(stats.batch_steps),
        static_cast<long long>(stats.batch_steps_on_clock),
        static_cast<long long>(stats.batch_steps_on_fill),
        static_cast<long long>(stats.batch_steps_on_merge),
        static_cast<long long>(stats.batch_steps_on_drift),
        static_cast<long long>(stats.batch_iterations), chi2, chi2_final_batch, chi2_reference,
        relative_difference, nnz_per_column,
        static_cast<long long>(stats.iterations_to_convergence),
        static_cast<double>(stats.rows_backsubstituted) / std::max<size_t>(1, step_ms.size()),
        static_cast<long long>(stats.givens_block_rows),
        static_cast<long long>(stats.givens_block_columns),
        static_cast<long long>(stats.partial_relinearizations), stats.partial_seconds,
        static_cast<long long>(stats.relinearized_variables),
        static_cast<long long>(stats.rows_reeliminated),
        static_cast<long long>(stats.rows_before_closure),
        static_cast<long long>(stats.rows_in_tails), static_cast<long long>(stats.partial_merges),
        static_cast<long long>(stats.correction_steps),
        static_cast<long long>(stats.correction_stalls),
        static_cast<long long>(stats.correction_skips), stats.correction_seconds,
        static_cast<long long>(work.gradient_passes),
        static_cast<long long>(work.factors_linearized), checks, worst_excess, failures,
        first_failure.c_str());
  } else {
    std::printf(
        "graph %s: %d poses, %d edges (%d encounters), %d robot(s), %d trajectories (%d broken "
        "odometry chain(s)), %s formulation\n",
        flags.graph.c_str(), replay.num_poses(), replay.num_edges(), replay.num_encounters(),
        replay.robots(), replay.num_trajectories(), replay.num_chain_breaks(),
        ToString(flags.smoother.formulation));
    std::printf("%s (%s, batch every %d, threshold %g): total %.3f s (%.3f s CPU)", mode, method,
                flags.smoother.batch_every_updates, flags.smoother.backsubstitution_threshold,
                total_s, total_cpu_s);
    if (flags.incremental) {
      std::printf(", step median %.3f ms, p99 %.3f ms, max %.3f ms", Percentile(step_ms, 0.5),
                  Percentile(step_ms, 0.99), Percentile(step_ms, 1.0));
    }
    std::printf("\ntime in batch steps %.3f s, in incremental steps %.3f s\n", stats.batch_seconds,
                stats.incremental_seconds);
    std::printf(
        "batch steps %lld (clock %lld, fill %lld, merge %lld, drift %lld), iterations %lld, "
        "iterations to 1e-4: %lld; partial merges %lld\n",
        static_cast<long long>(stats.batch_steps),
        static_cast<long long>(stats.batch_steps_on_clock),
        static_cast<long long>(stats.batch_steps_on_fill),
        static_cast<long long>(stats.batch_steps_on_merge),
        static_cast<long long>(stats.batch_steps_on_drift),
        static_cast<long long>(stats.batch_iterations),
        static_cast<long long>(stats.iterations_to_convergence),
        static_cast<long long>(stats.partial_merges));
    std::printf(
        "chi2 %.4f, after a final batch step %.4f, batch optimum %.4f (relative "
        "difference %.2e); nnz/column of R %.2f\n",
        chi2, chi2_final_batch, chi2_reference, relative_difference, nnz_per_column);
    if (stats.partial_relinearizations > 0) {
      std::printf(
          "partial relinearisations %lld (%.3f s): %.1f variables relinearised and %.1f block "
          "rows re-eliminated per step (%.1f marked before the elimination-tree closure; %.1f "
          "from the first of them to the end of R)\n",
          static_cast<long long>(stats.partial_relinearizations), stats.partial_seconds,
          static_cast<double>(stats.relinearized_variables) / stats.partial_relinearizations,
          static_cast<double>(stats.rows_reeliminated) / stats.partial_relinearizations,
          static_cast<double>(stats.rows_before_closure) / stats.partial_relinearizations,
          static_cast<double>(stats.rows_in_tails) / stats.partial_relinearizations);
    }
    if (flags.smoother.correction_tolerance > 0) {
      std::printf("correction: %lld steps, %lld updates not converged, %lld skipped (%.3f s)\n",
                  static_cast<long long>(stats.correction_steps),
                  static_cast<long long>(stats.correction_stalls),
                  static_cast<long long>(stats.correction_skips), stats.correction_seconds);
      std::printf("gradient passes %lld, factors linearised by them %lld (%.1f per pass)\n",
                  static_cast<long long>(work.gradient_passes),
                  static_cast<long long>(work.factors_linearized),
                  static_cast<double>(work.factors_linearized) /
                      std::max<int64_t>(1, work.gradient_passes));
    }
    if (checks > 0) {
      std::printf(
          "checked %d steps against their batch optimum: relative chi2 excess worst %.2e (step "
          "%d), mean %.2e\n",
          checks, worst_excess, worst_step, excess_sum / checks);
    }
    if (failures) std::printf("%d failure(s), first: %s\n", failures, first_failure.c_str());
  }
  return failures == 0 ? 0 : 1;
}

}  // namespace
}  // namespace anchormap

int main(int argc, char** argv) {
  anchormap::RetainFreedMemory();
  try {
    return anchormap::Run(anchormap::ParseFlags(argc, argv));
  } catch (const std::exception& e) {  // a bug: say what it was, exit non-zero
    std::fprintf(stderr, "anchormap-bench-solver: internal error: %s\n", e.what());
    return 3;
  }
}
