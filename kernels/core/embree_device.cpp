#include "kernels/core/embree_device.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <optional>
#include <vector>

#include <embree3/rtcore.h>
#include <fmt/format.h>

#include "kernels/core/closest_point.h"
#include "kernels/core/embree_scene.h"
#include "kernels/core/errors.h"

namespace gimforge {

// ---------------------------------------------------------------------------------------------------------
// EmbreeDevice

namespace {

/// Collects the first error Embree reports through its callback until EmbreeDevice::check reads it.
struct ErrorSink {
  std::mutex mutex;
  std::string pending;
};

const char* embree_error_name(RTCError code) {
  switch (code) {
    case RTC_ERROR_NONE: return "no error";
    case RTC_ERROR_UNKNOWN: return "unknown error";
    case RTC_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION: return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY: return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU: return "unsupported CPU";
    case RTC_ERROR_CANCELLED: return "cancelled";
  }
  return "unrecognised error";
}

void error_callback(void* user, RTCError code, const char* message) {
  auto* sink = static_cast<ErrorSink*>(user);
  std::lock_guard lock(sink->mutex);
  if (sink->pending.empty())
    sink->pending = fmt::format("{} ({})", embree_error_name(code), message ? message : "no message");
}

}  // namespace

struct EmbreeDevice::Impl {
  RTCDevice device{nullptr};
  mutable ErrorSink errors;
};

EmbreeDevice::EmbreeDevice(const std::string& config) : impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice(config.empty() ? nullptr : config.c_str());
  if (!impl_->device)
    throw LibraryError(fmt::format("Embree: cannot create a device ({})", embree_error_name(rtcGetDeviceError(nullptr))));
  rtcSetDeviceErrorFunction(impl_->device, error_callback, &impl_->errors);
}

EmbreeDevice::~EmbreeDevice() {
  if (impl_ && impl_->device) rtcReleaseDevice(impl_->device);
}
EmbreeDevice::EmbreeDevice(EmbreeDevice&&) noexcept = default;
EmbreeDevice& EmbreeDevice::operator=(EmbreeDevice&&) noexcept = default;

void* EmbreeDevice::native() const { return impl_->device; }

void EmbreeDevice::check(const char* what) const {
  std::string message;
  {
    std::lock_guard lock(impl_->errors.mutex);
    message.swap(impl_->errors.pending);
  }
  if (!message.empty()) throw LibraryError(fmt::format("Embree: {}: {}", what, message));
}

// ---------------------------------------------------------------------------------------------------------
// TriangleBvh

/// Bounding sphere of a face, inflated to cover float rounding: a cheap lower bound on the distance.
struct FaceSphere {
  float cx, cy, cz, radius;
};

struct TriangleBvh::Impl {
  const EmbreeDevice* device{nullptr};
  MeshView mesh;
  std::vector<FaceSphere> spheres;
  std::optional<detail::EmbreeScene> scene;
  double max_abs{0.0};  // largest |coordinate|: scales the slack covering float rounding
};

namespace {

struct QueryState {
  const MeshView* mesh;
  const FaceSphere* spheres;
  Vec3 p;
  double best2;  // squared distance of the best candidate so far
  double best;   // its square root
  double margin;
  ClosestPoint result;
};

bool point_query_callback(RTCPointQueryFunctionArguments* args) {
  auto* state = static_cast<QueryState*>(args->userPtr);
  // Reject faces whose bounding sphere lies entirely beyond the best distance so far (most candidates).
  const FaceSphere& sphere = state->spheres[args->primID];
  const double dx = state->p.x() - double{sphere.cx};
  const double dy = state->p.y() - double{sphere.cy};
  const double dz = state->p.z() - double{sphere.cz};
  const double reach = state->best + double{sphere.radius};
  if (dx * dx + dy * dy + dz * dz > reach * reach) return false;
  const Face& t = state->mesh->faces[args->primID];
  const auto& pos = state->mesh->positions;
  const TrianglePoint tp = closest_point_on_triangle(state->p, pos[t[0]], pos[t[1]], pos[t[2]]);
  const double d2 = (tp.point - state->p).squaredNorm();
  if (d2 < state->best2) {
    state->best2 = d2;
    state->best = std::sqrt(d2);
    state->result.point = tp.point;
    state->result.barycentric = tp.barycentric;
    state->result.face = args->primID;
    args->query->radius = static_cast<float>(state->best + state->margin);
    return true;  // the query radius shrank
  }
  return false;
}

}  // namespace

TriangleBvh::TriangleBvh(const EmbreeDevice& device, MeshView mesh) : impl_(std::make_unique<Impl>()) {
  if (mesh.faces.empty()) throw InvalidInput("TriangleBvh: mesh has no faces");
  impl_->device = &device;
  impl_->mesh = mesh;
  double max_abs = 0.0;
  for (const Vec3& p : mesh.positions) max_abs = std::max(max_abs, p.cwiseAbs().maxCoeff());
  impl_->max_abs = max_abs;
  // Face spheres centred at the vertex average; radius inflated by float rounding of centre and radius.
  impl_->spheres.resize(mesh.faces.size());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Face& t = mesh.faces[f];
    const Vec3 c = (mesh.positions[t[0]] + mesh.positions[t[1]] + mesh.positions[t[2]]) / 3.0;
    double r = 0.0;
    for (std::uint32_t v : t) r = std::max(r, (mesh.positions[v] - c).norm());
    impl_->spheres[f] = {static_cast<float>(c.x()), static_cast<float>(c.y()), static_cast<float>(c.z()),
                         static_cast<float>(r * (1.0 + 1e-5) + 1e-6 * std::max(max_abs, 1e-30))};
  }
  impl_->scene.emplace(device, mesh.positions, mesh.faces, RTC_BUILD_QUALITY_HIGH, "building the triangle BVH");
}

TriangleBvh::~TriangleBvh() = default;
TriangleBvh::TriangleBvh(TriangleBvh&&) noexcept = default;
TriangleBvh& TriangleBvh::operator=(TriangleBvh&&) noexcept = default;

MeshView TriangleBvh::mesh() const { return impl_->mesh; }

void* TriangleBvh::native_scene() const { return impl_->scene->get(); }

double TriangleBvh::distance_to_face(const Vec3& p, std::uint32_t f) const {
  const Face& t = impl_->mesh.faces[f];
  const auto& pos = impl_->mesh.positions;
  return std::sqrt(squared_distance_to_triangle(p, pos[t[0]], pos[t[1]], pos[t[2]]));
}

ClosestPoint TriangleBvh::closest_point(const Vec3& p, double upper_bound) const {
  // Float rounding of the coordinates, the BVH bounds and the query point is a few ulps (2^-24 relative)
  // of the largest coordinate involved; 1e-6 of it is a safe slack for the traversal radius.
  const double margin = 1e-6 * std::max({impl_->max_abs, std::abs(p.x()), std::abs(p.y()), std::abs(p.z()), 1e-30});
  const double inf = std::numeric_limits<double>::infinity();
  QueryState state{&impl_->mesh, impl_->spheres.data(), p, inf, inf, margin, {}};
  if (std::isfinite(upper_bound)) {
    // Slightly above the bound, so that the face the bound came from is still accepted.
    state.best2 = upper_bound * upper_bound * (1.0 + 1e-9) + 1e-300;
    state.best = std::sqrt(state.best2);
  }
  RTCPointQuery query;
  query.x = static_cast<float>(p.x());
  query.y = static_cast<float>(p.y());
  query.z = static_cast<float>(p.z());
  query.time = 0.0f;
  query.radius = std::isfinite(upper_bound) ? static_cast<float>(upper_bound * (1.0 + 1e-6) + margin)
                                            : std::numeric_limits<float>::infinity();
  RTCPointQueryContext context;
  rtcInitPointQueryContext(&context);
  rtcPointQuery(impl_->scene->get(), &query, &context, point_query_callback, &state);
  if (state.result.found()) state.result.distance = state.best;
  return state.result;
}

}  // namespace gimforge
