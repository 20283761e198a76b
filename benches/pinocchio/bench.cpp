// The Pinocchio reference for `spatial_dynamics bench`: the same kernels, timed the same way,
// printed as the same JSON object.
//
//   bench URDF [--floating-base] [--frame LINK] [--states N] [--repeats N] [--min-time SECONDS]
//
// Kernels (Pinocchio's own algorithms, compiled from its headers):
//   rnea            pinocchio::rnea(q, v, a)
//   crba            pinocchio::crba(q)            fills the upper triangle of data.M only
//   fd_aba          pinocchio::aba(q, v, tau)
//   fd_crba         nonLinearEffects(q, v), crba(q), cholesky::decompose, cholesky::solve
//                   on tau - nle (Pinocchio's sparse LDLᵀ of M; no explicit inverse)
//   fd_rnea_columns C = nonLinearEffects(q, v), column k of M = rnea(q, v, e_k) - C, then a
//                   dense Eigen LLT: the same method as ours, built from Pinocchio's rnea
//   gravity         computeGeneralizedGravity(q)
//   frame_jacobian  computeFrameJacobian(q, LINK, WORLD) of the BODY frame of --frame (our bench
//                   names its link as "frame"); null without --frame
//   center_of_mass  jacobianCenterOfMass(q): the centre of mass (subtree ones too) and its
//                   3 × nv Jacobian
//   rnea_derivatives computeRNEADerivatives(q, v, a): ∂τ/∂q, ∂τ/∂v and M (upper triangle)
//   aba_derivatives  computeABADerivatives(q, v, tau): ∂q̈/∂q, ∂q̈/∂v and M⁻¹ (upper triangle)
// crba, aba (and so fd_crba) take a Convention (LOCAL, the default, or WORLD); both are timed,
// the faster is reported under the main key and both under "detail".
//
// Random states: pinocchio::randomConfiguration within the joint limits, each limit clipped to
// [-1.5, 1.5] (so free-flyer translations are finite; rotations are uniform unit quaternions),
// v, a and tau uniform in [-1, 1]. They are generated before timing and cycled through; each
// kernel is warmed up, then timed over several repeats of whole passes through the states with
// one clock read around many calls; the median repeat is reported.

#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/center-of-mass.hpp>
#include <pinocchio/algorithm/cholesky.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <Eigen/Cholesky>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;
using Eigen::VectorXd;

// Like std::hint::black_box: the compiler must assume `p` is read and memory written.
template <class T>
inline void escape(T const *p) {
  asm volatile("" : : "g"(p) : "memory");
}

struct State {
  VectorXd q, v, a_or_tau;
};

struct Settings {
  int states = 1024;
  int repeats = 7;
  double min_time = 0.2;
};

// Median nanoseconds per call, cycling through the states.
template <class F>
double measure(const std::vector<State> &states, const Settings &settings, F &&call) {
  auto pass = [&] {
    auto start = Clock::now();
    for (const State &s : states) {
      escape(&s);
      call(s);
    }
    return std::chrono::duration<double>(Clock::now() - start).count();
  };
  // Warm-up (half a repeat's time), which also measures how many passes fill a repeat.
  double warm = 0.0;
  int warm_passes = 0;
  while (warm < settings.min_time / 2.0 || warm_passes == 0) {
    warm += pass();
    ++warm_passes;
  }
  double per_pass = std::max(warm / warm_passes, 1e-9);
  int passes = std::max(1, static_cast<int>(std::ceil(settings.min_time / per_pass)));
  std::vector<double> samples;
  for (int r = 0; r < settings.repeats; ++r) {
    double total = 0.0;
    for (int p = 0; p < passes; ++p) total += pass();
    samples.push_back(total * 1e9 / (static_cast<double>(passes) * states.size()));
  }
  std::sort(samples.begin(), samples.end());
  return samples[samples.size() / 2];
}

[[noreturn]] void usage(const char *message) {
  std::fprintf(stderr,
               "bench: %s\nusage: bench URDF [--floating-base] [--frame LINK] [--states N] "
               "[--repeats N] [--min-time SECONDS]\n",
               message);
  std::exit(2);
}

}  // namespace

int main(int argc, char **argv) {
  std::string urdf, frame;
  bool floating_base = false;
  Settings settings;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    auto value = [&]() -> const char * {
      if (i + 1 >= argc) usage(("missing value after " + arg).c_str());
      return argv[++i];
    };
    if (arg == "--floating-base") {
      floating_base = true;
    } else if (arg == "--frame") {
      frame = value();
    } else if (arg == "--states") {
      settings.states = std::atoi(value());
    } else if (arg == "--repeats") {
      settings.repeats = std::atoi(value());
    } else if (arg == "--min-time") {
      settings.min_time = std::atof(value());
    } else if (!arg.empty() && arg[0] != '-' && urdf.empty()) {
      urdf = arg;
    } else {
      usage(("unexpected argument " + arg).c_str());
    }
  }
  if (urdf.empty()) usage("no URDF given");
  if (settings.states < 1 || settings.repeats < 1 || !(settings.min_time > 0.0)) {
    usage("--states and --repeats must be at least 1, --min-time positive");
  }

  pinocchio::Model model;
  // Mimic joints are independent (buildModel's default), like `spatial_dynamics --ignore-mimic`.
  if (floating_base) {
    pinocchio::urdf::buildModel(urdf, pinocchio::JointModelFreeFlyer(), model);
  } else {
    pinocchio::urdf::buildModel(urdf, model);
  }
  pinocchio::Data data(model);
  const int nv = model.nv;

  std::srand(12345);
  VectorXd lower = model.lowerPositionLimit.cwiseMax(-1.5).cwiseMin(1.5);
  VectorXd upper = model.upperPositionLimit.cwiseMin(1.5).cwiseMax(lower);
  std::vector<State> states(settings.states);
  for (State &s : states) {
    s.q = pinocchio::randomConfiguration(model, lower, upper);
    s.v = VectorXd::Random(nv);
    s.a_or_tau = VectorXd::Random(nv);
  }

  using pinocchio::Convention;
  const Convention conventions[2] = {Convention::LOCAL, Convention::WORLD};
  const char *convention_names[2] = {"local", "world"};

  // Scratch for the forward-dynamics variants, allocated once.
  VectorXd rhs(nv), bias(nv), unit = VectorXd::Zero(nv);
  Eigen::MatrixXd mass(nv, nv);
  Eigen::LLT<Eigen::MatrixXd> llt(nv);

  double rnea_ns = measure(states, settings, [&](const State &s) {
    pinocchio::rnea(model, data, s.q, s.v, s.a_or_tau);
    escape(data.tau.data());
  });
  double crba_ns[2], aba_ns[2], fd_crba_ns[2];
  for (int c = 0; c < 2; ++c) {
    const Convention conv = conventions[c];
    crba_ns[c] = measure(states, settings, [&](const State &s) {
      pinocchio::crba(model, data, s.q, conv);
      escape(data.M.data());
    });
    aba_ns[c] = measure(states, settings, [&](const State &s) {
      pinocchio::aba(model, data, s.q, s.v, s.a_or_tau, conv);
      escape(data.ddq.data());
    });
    fd_crba_ns[c] = measure(states, settings, [&](const State &s) {
      pinocchio::nonLinearEffects(model, data, s.q, s.v);
      pinocchio::crba(model, data, s.q, conv);
      pinocchio::cholesky::decompose(model, data);
      rhs = s.a_or_tau - data.nle;
      pinocchio::cholesky::solve(model, data, rhs);
      escape(rhs.data());
    });
  }
  double fd_rnea_columns_ns = measure(states, settings, [&](const State &s) {
    bias = pinocchio::nonLinearEffects(model, data, s.q, s.v);
    for (int k = 0; k < nv; ++k) {
      unit[k] = 1.0;
      mass.col(k) = pinocchio::rnea(model, data, s.q, s.v, unit) - bias;
      unit[k] = 0.0;
    }
    llt.compute(mass);
    rhs = s.a_or_tau - bias;
    llt.solveInPlace(rhs);
    escape(rhs.data());
  });
  double gravity_ns = measure(states, settings, [&](const State &s) {
    pinocchio::computeGeneralizedGravity(model, data, s.q);
    escape(data.g.data());
  });

  double frame_jacobian_ns = -1.0;
  if (!frame.empty()) {
    if (!model.existFrame(frame, pinocchio::BODY)) usage(("no link named " + frame).c_str());
    const pinocchio::FrameIndex id = model.getFrameId(frame, pinocchio::BODY);
    Eigen::MatrixXd jacobian = Eigen::MatrixXd::Zero(6, nv);
    frame_jacobian_ns = measure(states, settings, [&](const State &s) {
      pinocchio::computeFrameJacobian(model, data, s.q, id, pinocchio::WORLD, jacobian);
      escape(jacobian.data());
    });
  }
  double center_of_mass_ns = measure(states, settings, [&](const State &s) {
    pinocchio::jacobianCenterOfMass(model, data, s.q);
    escape(data.Jcom.data());
  });

  double rnea_derivatives_ns = measure(states, settings, [&](const State &s) {
    pinocchio::computeRNEADerivatives(model, data, s.q, s.v, s.a_or_tau);
    escape(data.dtau_dq.data());
    escape(data.dtau_dv.data());
    escape(data.M.data());
  });
  double aba_derivatives_ns = measure(states, settings, [&](const State &s) {
    pinocchio::computeABADerivatives(model, data, s.q, s.v, s.a_or_tau);
    escape(data.ddq_dq.data());
    escape(data.ddq_dv.data());
    escape(data.Minv.data());
  });

  auto best = [](const double (&x)[2]) { return std::min(x[0], x[1]); };
  std::printf("{\"nv\": %d, \"ns_per_call\": {\"rnea\": %.1f, \"crba\": %.1f, \"fd_aba\": %.1f, "
              "\"fd_crba\": %.1f, \"fd_rnea_columns\": %.1f, \"gravity\": %.1f, ",
              nv, rnea_ns, best(crba_ns), best(aba_ns), best(fd_crba_ns), fd_rnea_columns_ns,
              gravity_ns);
  if (frame_jacobian_ns < 0.0) {
    std::printf("\"frame_jacobian\": null, ");
  } else {
    std::printf("\"frame_jacobian\": %.1f, ", frame_jacobian_ns);
  }
  std::printf("\"center_of_mass\": %.1f, \"rnea_derivatives\": %.1f, \"aba_derivatives\": %.1f}, ",
              center_of_mass_ns, rnea_derivatives_ns, aba_derivatives_ns);
  std::printf("\"detail\": {\"pinocchio\": \"%s\", \"nq\": %d", PINOCCHIO_VERSION, model.nq);
  for (int c = 0; c < 2; ++c) {
    std::printf(", \"crba_%s\": %.1f, \"aba_%s\": %.1f, \"fd_crba_%s\": %.1f", convention_names[c],
                crba_ns[c], convention_names[c], aba_ns[c], convention_names[c], fd_crba_ns[c]);
  }
  std::printf("}}\n");
  return 0;
}
