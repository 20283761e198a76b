// Gravity compensation at 1 kHz: the efforts g(q) that hold a robot still, computed in-process
// as a ros2_control controller's update() would, timed per call.
//
//   gravity_compensation ROBOT.urdf [SECONDS]
//
// Loads the URDF (fixed base), then for SECONDS (default 1; a number greater than 0 and at
// most 3600) wakes every millisecond, moves q along a slow sine about zero and computes g(q),
// timing each call. Prints the per-call time (min, median, 99th percentile, max, in µs), how
// many deadlines the loop missed, and g at the last q by coordinate name. Exits 2 with the
// usage on bad arguments, 1 with the error's message (the library's, or running out of
// memory) on any other error.
#include "spatial_dynamics.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <thread>
#include <vector>

namespace {
// The longest run, an hour: each call's time is kept in memory, twice to sort it (58 MB then).
constexpr double kMaxSeconds = 3600.0;

// `text` as a number of seconds in (0, kMaxSeconds], or NAN when it is anything else.
double parse_seconds(const char* text) {
  char* end = nullptr;
  const double seconds = std::strtod(text, &end);
  if (end == text || *end != '\0' || !(seconds > 0.0 && seconds <= kMaxSeconds)) return NAN;
  return seconds;
}
}  // namespace

int main(int argc, char** argv) {
  const double seconds = argc == 3 ? parse_seconds(argv[2]) : 1.0;
  if (argc < 2 || argc > 3 || std::isnan(seconds)) {
    if (argc == 3 && std::isnan(seconds)) {
      std::fprintf(stderr, "%s: SECONDS '%s' is not a number greater than 0 and at most %g\n",
                   argv[0], argv[2], kMaxSeconds);
    }
    std::fprintf(stderr, "usage: %s ROBOT.urdf [SECONDS]\n", argv[0]);
    return 2;
  }
  try {
    const sd::Model model = sd::Model::from_urdf_file(argv[1]);
    sd::Workspace ws(model);
    std::vector<double> q(model.nq(), 0.0), g(model.nv(), 0.0);
    const auto period = std::chrono::microseconds(1000);
    const long steps = std::max(1L, std::lround(seconds * 1000.0));
    std::vector<double> per_call_us;
    per_call_us.reserve(steps);
    long missed = 0;
    using clock = std::chrono::steady_clock;
    auto wake = clock::now();
    for (long step = 0; step < steps; ++step) {
      const double t = step * 1e-3;
      for (std::size_t i = 0; i < q.size(); ++i) q[i] = 0.5 * std::sin(0.5 * t + 0.3 * i);
      const auto start = clock::now();
      sd::gravity(model, ws, q, g);  // the real-time part: no allocation, no lock
      const auto stop = clock::now();
      per_call_us.push_back(std::chrono::duration<double, std::micro>(stop - start).count());
      wake += period;
      if (clock::now() > wake) ++missed;
      std::this_thread::sleep_until(wake);
    }
    std::vector<double> sorted = per_call_us;
    std::sort(sorted.begin(), sorted.end());
    const auto at = [&](double fraction) {
      return sorted[std::min(sorted.size() - 1, static_cast<std::size_t>(fraction * sorted.size()))];
    };
    std::printf("%ld calls of g(q) at 1 kHz on %zu coordinates: per call min %.2f us, median %.2f us, "
                "p99 %.2f us, max %.2f us; %ld deadlines missed\n",
                steps, model.nv(), sorted.front(), at(0.5), at(0.99), sorted.back(), missed);
    for (std::size_t i = 0; i < g.size(); ++i) {
      const std::string_view name = model.v_name(i);
      std::printf("g[%.*s] = %.9g\n", static_cast<int>(name.size()), name.data(), g[i]);
    }
  } catch (const std::exception& e) {  // sd::Error, or std::bad_alloc
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
