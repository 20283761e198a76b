// spatial_dynamics: rigid-body dynamics of URDF robots, called in-process from C++.
//
// Header-only, over the C ABI of spatial_dynamics.h (link libspatial_dynamics_c; with CMake,
// find_package(spatial_dynamics_c) and the target spatial_dynamics_c::spatial_dynamics_c).
// sd::Model and sd::Workspace own their C objects (movable, not copyable: a moved-from object
// owns none, and assigning to one frees the C object it owned); every function throws
// sd::Error, carrying the library's message, when the C call fails. Made once, outside
// a real-time loop, a model and its workspace serve calls that allocate nothing (an error
// allocates its message). The array overloads take std::span (C++20) and check lengths; the
// pointer overloads take arrays of the lengths the model gives (nq for q, nv for velocities,
// accelerations and efforts, nv·nv for the mass matrix, 6·nv for a Jacobian). Conventions:
// coordinates in the order of Model::v_name, matrices row-major, SI units (see
// spatial_dynamics.h for each function's quantities and frames).
#ifndef SPATIAL_DYNAMICS_HPP
#define SPATIAL_DYNAMICS_HPP

#include "spatial_dynamics.h"

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#if __has_include(<span>)
#include <span>
#endif

namespace sd {

// A failed call: what() is the library's message (the function, and the joint, coordinate,
// link or value at fault); status() the sd_status code (for the C functions that return NULL
// on failure, the code sd_last_status() gives). A path or URDF text holding a NUL byte, which
// the C functions would read as its end, is refused before the C call with SD_ERROR_USAGE.
class Error : public std::runtime_error {
 public:
  Error(int status, const std::string& message) : std::runtime_error(message), status_(status) {}
  int status() const noexcept { return status_; }

 private:
  int status_;
};

namespace detail {
// Throws the C library's last error when `status` is not SD_OK.
inline void check(int status) {
  if (status != SD_OK) {
    const char* message = sd_last_error();
    throw Error(status, message ? message : "spatial_dynamics: unknown error");
  }
}

// Throws the C library's last error when `made` (what a C function returning a pointer gave)
// is NULL.
inline void check_made(const void* made) {
  if (!made) {
    const int status = sd_last_status();
    check(status != SD_OK ? status : SD_ERROR_INTERNAL);
  }
}

// Throws SD_ERROR_USAGE when `text` holds a NUL byte: the C function it is passed to as a C
// string would stop reading there.
inline void check_no_nul(const char* function, const char* argument, const std::string& text) {
  const std::size_t nul = text.find('\0');
  if (nul != std::string::npos) {
    throw Error(SD_ERROR_USAGE, std::string(function) + ": " + argument +
                                    " holds a NUL byte at offset " + std::to_string(nul) +
                                    " (of " + std::to_string(text.size()) + ")");
  }
}
}  // namespace detail

// The frame a Jacobian is expressed in, with Pinocchio's meaning (pinocchio::ReferenceFrame).
enum class Reference : int {
  World = SD_WORLD,                            // world axes, about the world origin
  Local = SD_LOCAL,                            // link axes, at the link origin
  LocalWorldAligned = SD_LOCAL_WORLD_ALIGNED,  // world axes, at the link origin
};

// Choices made when a model is built.
struct ModelOptions {
  bool floating_base = false;  // a floating joint between the world and the root link
  bool ignore_mimic = false;   // <mimic> joints get coordinates of their own
};

// A robot model (immutable), built from URDF. A moved-from model owns no C model: its nq() and
// nv() are 0, and v_name(), forward_dynamics_method(), a Workspace made for it and every call
// given it throw SD_ERROR_USAGE. Assigning to a model frees the C model it owned, so the
// workspaces made for that one must be gone by then.
class Model {
 public:
  // The model of the URDF file at `path` (UTF-8, no NUL byte).
  static Model from_urdf_file(const std::string& path, ModelOptions options = {}) {
    detail::check_no_nul("sd::Model::from_urdf_file", "path", path);
    const sd_model_options c = to_c(options);
    return Model(made(sd_model_from_urdf_file(path.c_str(), &c)));
  }
  // The model of URDF text `urdf` (UTF-8, no NUL byte).
  static Model from_urdf_string(const std::string& urdf, ModelOptions options = {}) {
    detail::check_no_nul("sd::Model::from_urdf_string", "urdf", urdf);
    const sd_model_options c = to_c(options);
    return Model(made(sd_model_from_urdf_string(urdf.c_str(), &c)));
  }

  Model(Model&& other) noexcept : model_(std::exchange(other.model_, nullptr)) {}
  // Frees this model's C model and takes `other`'s, leaving `other` moved-from (self-assignment
  // changes nothing).
  Model& operator=(Model&& other) noexcept {
    if (this != &other) {
      sd_model_free(model_);
      model_ = std::exchange(other.model_, nullptr);
    }
    return *this;
  }
  Model(const Model&) = delete;
  Model& operator=(const Model&) = delete;
  ~Model() { sd_model_free(model_); }

  // Position and velocity coordinates.
  std::size_t nq() const noexcept { return sd_model_nq(model_); }
  std::size_t nv() const noexcept { return sd_model_nv(model_); }
  // The name of velocity coordinate `index` (throws for index >= nv).
  std::string_view v_name(std::size_t index) const {
    const char* name = sd_model_v_name(model_, index);
    detail::check_made(name);
    return name;
  }
  // "aba", "crba" or "rnea_columns": the method forward_dynamics uses for this model (throws
  // on a moved-from model, whose nq() and nv() are 0).
  std::string_view forward_dynamics_method() const {
    const char* name = sd_model_forward_dynamics_method(model_);
    detail::check_made(name);
    return name;
  }
  // The C handle (owned by this object).
  const sd_model* get() const noexcept { return model_; }

 private:
  explicit Model(sd_model* model) : model_(model) {}
  static sd_model* made(sd_model* model) {
    detail::check_made(model);
    return model;
  }
  static sd_model_options to_c(ModelOptions options) {
    return sd_model_options{options.floating_base ? 1 : 0, options.ignore_mimic ? 1 : 0};
  }
  sd_model* model_;
};

// The scratch buffers of one model's calls; one per thread. Must not outlive its model's C
// model (the Model's destruction, or an assignment to it). A moved-from workspace owns none:
// every call given it throws SD_ERROR_USAGE.
class Workspace {
 public:
  explicit Workspace(const Model& model) : workspace_(sd_workspace_new(model.get())) {
    detail::check_made(workspace_);
  }
  Workspace(Workspace&& other) noexcept : workspace_(std::exchange(other.workspace_, nullptr)) {}
  // Frees this workspace's C workspace and takes `other`'s, leaving `other` moved-from
  // (self-assignment changes nothing).
  Workspace& operator=(Workspace&& other) noexcept {
    if (this != &other) {
      sd_workspace_free(workspace_);
      workspace_ = std::exchange(other.workspace_, nullptr);
    }
    return *this;
  }
  Workspace(const Workspace&) = delete;
  Workspace& operator=(const Workspace&) = delete;
  ~Workspace() { sd_workspace_free(workspace_); }

  // The C handle (owned by this object).
  sd_workspace* get() const noexcept { return workspace_; }

 private:
  sd_workspace* workspace_;
};

// ---- raw arrays (lengths as the model gives them) -------------------------------------------

// Inverse dynamics: tau = M(q) a + C(q, v) + g(q).
inline void rnea(const Model& model, Workspace& ws, const double* q, const double* v,
                 const double* a, double* tau) {
  detail::check(sd_rnea(model.get(), ws.get(), q, v, a, tau));
}
// Generalized gravity g(q).
inline void gravity(const Model& model, Workspace& ws, const double* q, double* g) {
  detail::check(sd_gravity(model.get(), ws.get(), q, g));
}
// Forward dynamics: qdd = M(q)⁻¹ (tau − C(q, v) − g(q)).
inline void forward_dynamics(const Model& model, Workspace& ws, const double* q, const double* v,
                             const double* tau, double* qdd) {
  detail::check(sd_forward_dynamics(model.get(), ws.get(), q, v, tau, qdd));
}
// The mass matrix M(q), nv × nv, row-major.
inline void mass_matrix(const Model& model, Workspace& ws, const double* q, double* m) {
  detail::check(sd_mass_matrix(model.get(), ws.get(), q, m));
}
// The derivatives of inverse dynamics: dtau_dq, dtau_dv and m = M(q), each nv × nv, row-major.
inline void rnea_derivatives(const Model& model, Workspace& ws, const double* q, const double* v,
                             const double* a, double* dtau_dq, double* dtau_dv, double* m) {
  detail::check(sd_rnea_derivatives(model.get(), ws.get(), q, v, a, dtau_dq, dtau_dv, m));
}
// The derivatives of forward dynamics: ddq_dq, ddq_dv and minv = M(q)⁻¹, each nv × nv, row-major.
inline void aba_derivatives(const Model& model, Workspace& ws, const double* q, const double* v,
                            const double* tau, double* ddq_dq, double* ddq_dv, double* minv) {
  detail::check(sd_aba_derivatives(model.get(), ws.get(), q, v, tau, ddq_dq, ddq_dv, minv));
}
// The Jacobian of URDF link `frame`, 6 × nv, row-major, rows [linear; angular].
inline void frame_jacobian(const Model& model, Workspace& ws, const double* q, const char* frame,
                           Reference reference, double* j) {
  detail::check(
      sd_frame_jacobian(model.get(), ws.get(), q, frame, static_cast<int>(reference), j));
}

#if defined(__cpp_lib_span) && __cpp_lib_span >= 202002L
// ---- std::span (lengths checked) ------------------------------------------------------------

namespace detail {
// Throws SD_ERROR_USAGE when `array` does not have `expected` values.
inline void check_length(const char* function, const char* array, std::size_t size,
                         std::size_t expected) {
  if (size != expected) {
    throw Error(SD_ERROR_USAGE, std::string(function) + ": " + array + " has " +
                                    std::to_string(size) + " values, the model needs " +
                                    std::to_string(expected));
  }
}
}  // namespace detail

inline void rnea(const Model& model, Workspace& ws, std::span<const double> q,
                 std::span<const double> v, std::span<const double> a, std::span<double> tau) {
  const std::size_t nq = model.nq(), nv = model.nv();
  detail::check_length("sd::rnea", "q", q.size(), nq);
  detail::check_length("sd::rnea", "v", v.size(), nv);
  detail::check_length("sd::rnea", "a", a.size(), nv);
  detail::check_length("sd::rnea", "tau", tau.size(), nv);
  rnea(model, ws, q.data(), v.data(), a.data(), tau.data());
}
inline void gravity(const Model& model, Workspace& ws, std::span<const double> q,
                    std::span<double> g) {
  detail::check_length("sd::gravity", "q", q.size(), model.nq());
  detail::check_length("sd::gravity", "g", g.size(), model.nv());
  gravity(model, ws, q.data(), g.data());
}
inline void forward_dynamics(const Model& model, Workspace& ws, std::span<const double> q,
                             std::span<const double> v, std::span<const double> tau,
                             std::span<double> qdd) {
  const std::size_t nq = model.nq(), nv = model.nv();
  detail::check_length("sd::forward_dynamics", "q", q.size(), nq);
  detail::check_length("sd::forward_dynamics", "v", v.size(), nv);
  detail::check_length("sd::forward_dynamics", "tau", tau.size(), nv);
  detail::check_length("sd::forward_dynamics", "qdd", qdd.size(), nv);
  forward_dynamics(model, ws, q.data(), v.data(), tau.data(), qdd.data());
}
inline void mass_matrix(const Model& model, Workspace& ws, std::span<const double> q,
                        std::span<double> m) {
  detail::check_length("sd::mass_matrix", "q", q.size(), model.nq());
  detail::check_length("sd::mass_matrix", "m", m.size(), model.nv() * model.nv());
  mass_matrix(model, ws, q.data(), m.data());
}
inline void rnea_derivatives(const Model& model, Workspace& ws, std::span<const double> q,
                             std::span<const double> v, std::span<const double> a,
                             std::span<double> dtau_dq, std::span<double> dtau_dv,
                             std::span<double> m) {
  const std::size_t nq = model.nq(), nv = model.nv();
  detail::check_length("sd::rnea_derivatives", "q", q.size(), nq);
  detail::check_length("sd::rnea_derivatives", "v", v.size(), nv);
  detail::check_length("sd::rnea_derivatives", "a", a.size(), nv);
  detail::check_length("sd::rnea_derivatives", "dtau_dq", dtau_dq.size(), nv * nv);
  detail::check_length("sd::rnea_derivatives", "dtau_dv", dtau_dv.size(), nv * nv);
  detail::check_length("sd::rnea_derivatives", "m", m.size(), nv * nv);
  rnea_derivatives(model, ws, q.data(), v.data(), a.data(), dtau_dq.data(), dtau_dv.data(),
                   m.data());
}
inline void aba_derivatives(const Model& model, Workspace& ws, std::span<const double> q,
                            std::span<const double> v, std::span<const double> tau,
                            std::span<double> ddq_dq, std::span<double> ddq_dv,
                            std::span<double> minv) {
  const std::size_t nq = model.nq(), nv = model.nv();
  detail::check_length("sd::aba_derivatives", "q", q.size(), nq);
  detail::check_length("sd::aba_derivatives", "v", v.size(), nv);
  detail::check_length("sd::aba_derivatives", "tau", tau.size(), nv);
  detail::check_length("sd::aba_derivatives", "ddq_dq", ddq_dq.size(), nv * nv);
  detail::check_length("sd::aba_derivatives", "ddq_dv", ddq_dv.size(), nv * nv);
  detail::check_length("sd::aba_derivatives", "minv", minv.size(), nv * nv);
  aba_derivatives(model, ws, q.data(), v.data(), tau.data(), ddq_dq.data(), ddq_dv.data(),
                  minv.data());
}
inline void frame_jacobian(const Model& model, Workspace& ws, std::span<const double> q,
                           const char* frame, Reference reference, std::span<double> j) {
  detail::check_length("sd::frame_jacobian", "q", q.size(), model.nq());
  detail::check_length("sd::frame_jacobian", "j", j.size(), 6 * model.nv());
  frame_jacobian(model, ws, q.data(), frame, reference, j.data());
}
#endif

}  // namespace sd

#endif  // SPATIAL_DYNAMICS_HPP
