/* Reads a state on stdin and prints what the C ABI computes from it, for tests/python/test_c_abi.py.
 *
 *   probe ROBOT.urdf IGNORE_MIMIC FRAME  <  q (nq values) v a tau (nv values each)
 *
 * Prints one line per quantity, a name then its values: names (the v coordinates), tau =
 * RNEA(q, v, a), g(q), qdd = FD(q, v, tau), M(q) (row-major), J_world, J_local, J_aligned (the
 * Jacobian of FRAME, row-major). Then the errors of bad input, one line each, "error WHAT
 * STATUS MESSAGE": q with a NaN, an unknown frame, a description that does not parse. */
#include "spatial_dynamics.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static void print_values(const char *name, const double *x, size_t n) {
  printf("%s", name);
  for (size_t i = 0; i < n; ++i) printf(" %.17g", x[i]);
  printf("\n");
}

static int read_values(double *x, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (scanf("%lf", &x[i]) != 1) return 0;
  return 1;
}

static void print_error(const char *what, int status) {
  const char *message = sd_last_error();
  printf("error %s %d %s\n", what, status, message ? message : "(none)");
}

int main(int argc, char **argv) {
  if (argc != 4) return 2;
  sd_model_options options = {0, atoi(argv[2])};
  sd_model *model = sd_model_from_urdf_file(argv[1], &options);
  if (!model) {
    fprintf(stderr, "%s\n", sd_last_error());
    return 1;
  }
  sd_workspace *ws = sd_workspace_new(model);
  size_t nq = sd_model_nq(model), nv = sd_model_nv(model);
  double *q = malloc(nq * sizeof *q), *v = malloc(nv * sizeof *v), *a = malloc(nv * sizeof *a);
  double *tau_in = malloc(nv * sizeof *tau_in), *out = malloc(nv * nv * sizeof *out);
  double *j = malloc(6 * nv * sizeof *j);
  double *d1 = malloc(nv * nv * sizeof *d1), *d2 = malloc(nv * nv * sizeof *d2);
  if (!read_values(q, nq) || !read_values(v, nv) || !read_values(a, nv) || !read_values(tau_in, nv))
    return 2;
  printf("names");
  for (size_t i = 0; i < nv; ++i) printf(" %s", sd_model_v_name(model, i));
  printf("\n");
  int status = sd_rnea(model, ws, q, v, a, out);
  print_values("tau", out, nv);
  status |= sd_gravity(model, ws, q, out);
  print_values("g", out, nv);
  status |= sd_forward_dynamics(model, ws, q, v, tau_in, out);
  print_values("qdd", out, nv);
  status |= sd_mass_matrix(model, ws, q, out);
  print_values("M", out, nv * nv);
  status |= sd_rnea_derivatives(model, ws, q, v, a, d1, d2, out);
  print_values("dtau_dq", d1, nv * nv);
  print_values("dtau_dv", d2, nv * nv);
  print_values("M_rnea", out, nv * nv);
  status |= sd_aba_derivatives(model, ws, q, v, tau_in, d1, d2, out);
  print_values("ddq_dq", d1, nv * nv);
  print_values("ddq_dv", d2, nv * nv);
  print_values("Minv", out, nv * nv);
  const int references[3] = {SD_WORLD, SD_LOCAL, SD_LOCAL_WORLD_ALIGNED};
  const char *names[3] = {"J_world", "J_local", "J_aligned"};
  for (int r = 0; r < 3; ++r) {
    status |= sd_frame_jacobian(model, ws, q, argv[3], references[r], j);
    print_values(names[r], j, 6 * nv);
  }
  if (status != SD_OK) {
    fprintf(stderr, "%s\n", sd_last_error());
    return 1;
  }
  q[nq - 1] = NAN;
  print_error("nan", sd_gravity(model, ws, q, out));
  q[nq - 1] = 0.0;
  print_error("frame", sd_frame_jacobian(model, ws, q, "no_such_link", SD_WORLD, j));
  sd_model *bad = sd_model_from_urdf_string("<robot name='r'><link name='a'>", NULL);
  print_error("urdf", bad == NULL ? -1 : 0);
  sd_workspace_free(ws);
  sd_model_free(model);
  free(q), free(v), free(a), free(tau_in), free(out), free(j);
  return 0;
}
