// The C++ header's own behaviour, for tests/cpp.rs: moving sd::Model and sd::Workspace (by
// construction and by assignment, self-assignment included) and refusing a path or URDF text
// that holds a NUL byte. Run with the path of a fixed-base URDF; prints one line per failed
// check ("FAIL <line>: <what>") and exits 1 if any failed, else prints "ok".
#include "spatial_dynamics.hpp"

#include <cstdio>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace {
int failures = 0;

void expect(bool ok, int line, const std::string& what) {
  if (!ok) {
    std::printf("FAIL %d: %s\n", line, what.c_str());
    ++failures;
  }
}
#define EXPECT(condition) expect((condition), __LINE__, #condition)

// `call` throws sd::Error with `status` and a what() containing `needle`.
void expect_error(int line, const char* what, int status, const std::string& needle,
                  const std::function<void()>& call) {
  try {
    call();
    expect(false, line, std::string(what) + ": no error");
  } catch (const sd::Error& e) {
    expect(e.status() == status, line,
           std::string(what) + ": status " + std::to_string(e.status()) + ", not " +
               std::to_string(status) + " (" + e.what() + ")");
    expect(std::string(e.what()).find(needle) != std::string::npos, line,
           std::string(what) + ": '" + e.what() + "' does not contain '" + needle + "'");
  }
}
#define EXPECT_ERROR(status, needle, call) \
  expect_error(__LINE__, #call, status, needle, [&] { call; })

// g(q) at the zero configuration (the identity quaternion for a floating base) succeeds with
// this model and workspace.
bool gravity_runs(const sd::Model& model, sd::Workspace& ws) {
  std::vector<double> q(model.nq(), 0.0), g(model.nv(), 0.0);
  if (model.nq() > model.nv()) q[6] = 1.0;
  try {
    sd::gravity(model, ws, q, g);
    return true;
  } catch (const sd::Error& e) {
    std::printf("gravity: %s\n", e.what());
    return false;
  }
}

void model_moves(const std::string& path) {
  sd::ModelOptions floating;
  floating.floating_base = true;
  sd::Model a = sd::Model::from_urdf_file(path);
  sd::Model b = sd::Model::from_urdf_file(path, floating);
  const std::size_t nq = a.nq(), nv = a.nv();
  EXPECT(nq > 0 && b.nq() == nq + 7 && b.nv() == nv + 6);

  sd::Model c(std::move(a));
  EXPECT(a.get() == nullptr && a.nq() == 0 && a.nv() == 0);
  EXPECT(c.nq() == nq);

  // Assignment: c takes b's model, b owns none.
  c = std::move(b);
  EXPECT(c.nq() == nq + 7 && c.nv() == nv + 6);
  EXPECT(b.get() == nullptr);
  EXPECT(b.nq() == 0 && b.nv() == 0);
  EXPECT_ERROR(SD_ERROR_USAGE, "NULL", b.forward_dynamics_method());
  EXPECT_ERROR(SD_ERROR_USAGE, "NULL", b.v_name(0));
  EXPECT_ERROR(SD_ERROR_USAGE, "NULL", sd::Workspace{b});
  sd::Workspace for_c(c);
  EXPECT(gravity_runs(c, for_c));
  std::vector<double> q(c.nq(), 0.0), g(c.nv(), 0.0);
  EXPECT_ERROR(SD_ERROR_USAGE, "model", sd::gravity(b, for_c, q.data(), g.data()));

  // Self-assignment keeps the model.
  sd::Model& alias = c;
  c = std::move(alias);
  EXPECT(c.get() != nullptr && c.nq() == nq + 7);
  EXPECT(gravity_runs(c, for_c));

  // A moved-from model takes a model again by assignment.
  b = sd::Model::from_urdf_file(path);
  EXPECT(b.nq() == nq);
  sd::Workspace for_b(b);
  EXPECT(gravity_runs(b, for_b));
}

void workspace_moves(const std::string& path) {
  const sd::Model model = sd::Model::from_urdf_file(path);
  std::vector<double> q(model.nq(), 0.0), g(model.nv(), 0.0);
  sd::Workspace first(model), second(model);
  sd::Workspace third(std::move(first));
  EXPECT(first.get() == nullptr && third.get() != nullptr);
  EXPECT_ERROR(SD_ERROR_USAGE, "workspace", sd::gravity(model, first, q, g));

  third = std::move(second);
  EXPECT(second.get() == nullptr);
  EXPECT(third.get() != nullptr && gravity_runs(model, third));
  EXPECT_ERROR(SD_ERROR_USAGE, "workspace", sd::gravity(model, second, q, g));

  sd::Workspace& alias = third;
  third = std::move(alias);
  EXPECT(third.get() != nullptr && gravity_runs(model, third));
}

void nul_bytes(const std::string& path) {
  const std::string robot = "<robot name='r'><link name='a'/></robot>";
  EXPECT(sd::Model::from_urdf_string(robot).nv() == 0);
  const std::string text = robot + std::string("\0<not xml", 9);
  EXPECT_ERROR(SD_ERROR_USAGE, "urdf holds a NUL byte at offset 40",
               sd::Model::from_urdf_string(text));
  EXPECT_ERROR(SD_ERROR_USAGE, "path holds a NUL byte at offset " + std::to_string(path.size()),
               sd::Model::from_urdf_file(path + std::string("\0.ignored", 9)));
}
}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  try {
    model_moves(argv[1]);
    workspace_moves(argv[1]);
    nul_bytes(argv[1]);
  } catch (const sd::Error& e) {
    std::printf("FAIL: uncaught sd::Error %d: %s\n", e.status(), e.what());
    return 1;
  }
  if (failures > 0) return 1;
  std::printf("ok\n");
  return 0;
}
