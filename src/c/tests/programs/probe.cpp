// probe.c through the C++ header (sd::Model, sd::Workspace, std::span, sd::Error): the same
// arguments, input and output, for tests/python/test_c_abi.py; its error lines carry sd::Error's status and
// what(), and one more checks a span of the wrong length.
#include "spatial_dynamics.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <span>
#include <string>
#include <vector>

namespace {
void print_values(const char* name, std::span<const double> x) {
  std::printf("%s", name);
  for (double value : x) std::printf(" %.17g", value);
  std::printf("\n");
}

std::vector<double> read_values(std::size_t n) {
  std::vector<double> x(n);
  for (double& value : x)
    if (!(std::cin >> value)) std::exit(2);
  return x;
}

void print_error(const char* what, const std::function<void()>& call) {
  try {
    call();
    std::printf("error %s 0 (no error)\n", what);
  } catch (const sd::Error& e) {
    std::printf("error %s %d %s\n", what, e.status(), e.what());
  }
}
}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) return 2;
  try {
    sd::ModelOptions options;
    options.ignore_mimic = std::atoi(argv[2]) != 0;
    const sd::Model model = sd::Model::from_urdf_file(argv[1], options);
    sd::Workspace ws(model);
    const std::size_t nq = model.nq(), nv = model.nv();
    std::vector<double> q = read_values(nq), v = read_values(nv), a = read_values(nv),
                        tau = read_values(nv);
    std::vector<double> out(nv), m(nv * nv), j(6 * nv);
    std::printf("names");
    for (std::size_t i = 0; i < nv; ++i) std::printf(" %s", std::string(model.v_name(i)).c_str());
    std::printf("\n");
    sd::rnea(model, ws, q, v, a, out);
    print_values("tau", out);
    sd::gravity(model, ws, q, out);
    print_values("g", out);
    sd::forward_dynamics(model, ws, q, v, tau, out);
    print_values("qdd", out);
    sd::mass_matrix(model, ws, q, m);
    print_values("M", m);
    std::vector<double> d1(nv * nv), d2(nv * nv);
    sd::rnea_derivatives(model, ws, q, v, a, d1, d2, m);
    print_values("dtau_dq", d1);
    print_values("dtau_dv", d2);
    print_values("M_rnea", m);
    sd::aba_derivatives(model, ws, q, v, tau, d1, d2, m);
    print_values("ddq_dq", d1);
    print_values("ddq_dv", d2);
    print_values("Minv", m);
    const sd::Reference references[3] = {sd::Reference::World, sd::Reference::Local,
                                         sd::Reference::LocalWorldAligned};
    const char* names[3] = {"J_world", "J_local", "J_aligned"};
    for (int r = 0; r < 3; ++r) {
      sd::frame_jacobian(model, ws, q, argv[3], references[r], j);
      print_values(names[r], j);
    }
    q[nq - 1] = NAN;
    print_error("nan", [&] { sd::gravity(model, ws, q, out); });
    q[nq - 1] = 0.0;
    print_error("frame", [&] { sd::frame_jacobian(model, ws, q, "no_such_link", sd::Reference::World, j); });
    print_error("urdf", [] { sd::Model::from_urdf_string("<robot name='r'><link name='a'>"); });
    print_error("length", [&] { sd::gravity(model, ws, std::span<const double>(q).first(nq - 1), out); });
    sd::Workspace moved = std::move(ws);
    sd::gravity(model, moved, q, out);
  } catch (const sd::Error& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
