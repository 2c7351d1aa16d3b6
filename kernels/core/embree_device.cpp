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
  std::vector<FaceSphere> spheres;  // per primitive, in the BVH's frame
  std::optional<detail::EmbreeScene> scene;
  double max_abs{0.0};  // largest |coordinate| in the BVH's frame: scales the slack covering float rounding
  // split_outliers: the BVH's frame is the mesh's own minus `shift` (the median vertex), and outlier faces
  // are left out of the BVH and measured exactly on every query: primitive k is face prim_face[k].
  Vec3 shift{Vec3::Zero()};
  std::vector<std::uint32_t> prim_face;
  std::vector<std::uint32_t> far_faces;
  std::once_flag plain_once;                    // native_scene() of a split BVH: every face, own frame
  std::optional<detail::EmbreeScene> plain_scene;
};

namespace {

/// The float BVH's rounding slack is 1e-6 of the largest coordinate, for every query. Two cases made it far
/// larger than the mesh's triangles, so that each query near the mesh visited nearly all of them (`metrics`
/// of a 59K-face mesh with one stray vertex at 10^8: 52 s instead of 0.2 s):
/// - a few faces reaching far beyond the rest (a stray vertex of a scan): faces whose farthest vertex lies
///   more than kFarFactor times the median such distance from the median vertex are left out of the BVH
///   and measured on every query, when they are few (at most kFarFaces + faces/10^4);
/// - a mesh lying far from the origin of its frame (the other mesh of that `metrics`, whose local frame
///   the stray vertex placed 5·10^7 away): more than kShiftFactor times its median reach.
/// Either way the BVH is built around the median vertex. Distances are measured exactly in double in the
/// mesh's own frame whatever the BVH's frame, so the answers do not change, only the time.
constexpr double kFarFactor = 1024.0;
constexpr double kShiftFactor = 64.0;
constexpr std::size_t kFarFaces = 64;
constexpr std::size_t kMedianSample = 65536;  // the medians are estimated from a strided sample of this size

struct OutlierSplit {
  bool shifted{false};
  Vec3 centre{Vec3::Zero()};
  std::vector<std::uint32_t> far;  // the faces left out of the BVH
};

/// The median of `count` values value(i), estimated from every ⌈count / kMedianSample⌉-th one (deterministic:
/// the same mesh gives the same frame on every rank).
template <class Value>
double sampled_median(std::size_t count, Value value) {
  const std::size_t stride = (count + kMedianSample - 1) / kMedianSample;
  std::vector<double> sample;
  sample.reserve(count / stride + 1);
  for (std::size_t i = 0; i < count; i += stride) sample.push_back(value(i));
  const auto mid = sample.begin() + static_cast<std::ptrdiff_t>(sample.size() / 2);
  std::nth_element(sample.begin(), mid, sample.end());
  return *mid;
}

OutlierSplit split_outliers(const MeshView& mesh) {
  OutlierSplit out;
  const std::size_t n = mesh.faces.size();
  if (n < 256 || mesh.positions.empty()) return out;
  for (int k = 0; k < 3; ++k) out.centre[k] = sampled_median(mesh.positions.size(), [&](std::size_t i) { return mesh.positions[i][k]; });
  const auto reach = [&](std::size_t f) {
    double r = 0.0;
    for (const std::uint32_t v : mesh.faces[f]) r = std::max(r, (mesh.positions[v] - out.centre).cwiseAbs().maxCoeff());
    return r;
  };
  const double typical = sampled_median(n, reach);
  if (!(typical > 0.0) || !std::isfinite(typical)) return out;
  const double limit = kFarFactor * typical;
  const std::size_t most = kFarFaces + n / 10000;
  for (std::uint32_t f = 0; f < n && out.far.size() <= most; ++f)
    if (reach(f) > limit) out.far.push_back(f);
  if (out.far.size() > most) out.far.clear();  // many far faces: a mesh of that extent, not a few strays
  out.shifted = !out.far.empty() || out.centre.cwiseAbs().maxCoeff() > kShiftFactor * typical;
  return out;
}

struct QueryState {
  const MeshView* mesh;
  const FaceSphere* spheres;
  const std::uint32_t* prim_face;  // null: primitive = face
  Vec3 p;        // the query point, in the mesh's frame (exact distances)
  Vec3 q;        // the same point in the BVH's frame (sphere tests)
  double best2;  // squared distance of the best candidate so far
  double best;   // its square root
  double margin;
  ClosestPoint result;
};

/// Measures face f exactly; true when it is the best so far.
bool measure(QueryState& state, std::uint32_t f) {
  const Face& t = state.mesh->faces[f];
  const auto& pos = state.mesh->positions;
  const TrianglePoint tp = closest_point_on_triangle(state.p, pos[t[0]], pos[t[1]], pos[t[2]]);
  const double d2 = (tp.point - state.p).squaredNorm();
  if (!(d2 < state.best2)) return false;
  state.best2 = d2;
  state.best = std::sqrt(d2);
  state.result.point = tp.point;
  state.result.barycentric = tp.barycentric;
  state.result.face = f;
  return true;
}

bool point_query_callback(RTCPointQueryFunctionArguments* args) {
  auto* state = static_cast<QueryState*>(args->userPtr);
  // Reject faces whose bounding sphere lies entirely beyond the best distance so far (most candidates).
  const FaceSphere& sphere = state->spheres[args->primID];
  const double dx = state->q.x() - double{sphere.cx};
  const double dy = state->q.y() - double{sphere.cy};
  const double dz = state->q.z() - double{sphere.cz};
  const double reach = state->best + double{sphere.radius};
  if (dx * dx + dy * dy + dz * dz > reach * reach) return false;
  const std::uint32_t f = state->prim_face != nullptr ? state->prim_face[args->primID] : args->primID;
  if (!measure(*state, f)) return false;
  args->query->radius = static_cast<float>(state->best + state->margin);
  return true;  // the query radius shrank
}

}  // namespace

TriangleBvh::TriangleBvh(const EmbreeDevice& device, MeshView mesh) : impl_(std::make_unique<Impl>()) {
  if (mesh.faces.empty()) throw InvalidInput("TriangleBvh: mesh has no faces");
  impl_->device = &device;
  impl_->mesh = mesh;
  OutlierSplit split = split_outliers(mesh);
  if (split.shifted) impl_->shift = split.centre;
  std::vector<Face> near;  // the faces in the BVH, when not all
  if (!split.far.empty()) {
    impl_->far_faces = std::move(split.far);
    std::size_t next = 0;
    for (std::uint32_t f = 0; f < mesh.faces.size(); ++f) {
      if (next < impl_->far_faces.size() && impl_->far_faces[next] == f) {
        ++next;
      } else {
        impl_->prim_face.push_back(f);
        near.push_back(mesh.faces[f]);
      }
    }
  }
  const std::span<const Face> faces = near.empty() ? mesh.faces : std::span<const Face>(near);
  const Vec3& shift = impl_->shift;  // positions in the BVH's frame: mesh.positions[v] − shift
  double max_abs = 0.0;
  if (near.empty()) {
    for (const Vec3& p : mesh.positions) max_abs = std::max(max_abs, (p - shift).cwiseAbs().maxCoeff());
  } else {
    for (const Face& t : faces)
      for (const std::uint32_t v : t) max_abs = std::max(max_abs, (mesh.positions[v] - shift).cwiseAbs().maxCoeff());
  }
  impl_->max_abs = max_abs;
  // Face spheres centred at the vertex average; radius inflated by float rounding of centre and radius.
  impl_->spheres.resize(faces.size());
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const Face& t = faces[f];
    const Vec3 c = (mesh.positions[t[0]] + mesh.positions[t[1]] + mesh.positions[t[2]]) / 3.0 - shift;
    double r = 0.0;
    for (std::uint32_t v : t) r = std::max(r, (mesh.positions[v] - shift - c).norm());
    impl_->spheres[f] = {static_cast<float>(c.x()), static_cast<float>(c.y()), static_cast<float>(c.z()),
                         static_cast<float>(r * (1.0 + 1e-5) + 1e-6 * std::max(max_abs, 1e-30))};
  }
  impl_->scene.emplace(device, mesh.positions, faces, RTC_BUILD_QUALITY_HIGH, "building the triangle BVH", shift);
}

TriangleBvh::~TriangleBvh() = default;
TriangleBvh::TriangleBvh(TriangleBvh&&) noexcept = default;
TriangleBvh& TriangleBvh::operator=(TriangleBvh&&) noexcept = default;

MeshView TriangleBvh::mesh() const { return impl_->mesh; }

void* TriangleBvh::native_scene() const {
  if (impl_->shift == Vec3::Zero() && impl_->far_faces.empty()) return impl_->scene->get();
  // Shifted or outliers split off: ray casters get every face, primitive i = face i, in the mesh's own frame.
  std::call_once(impl_->plain_once, [&] {
    impl_->plain_scene.emplace(*impl_->device, impl_->mesh.positions, impl_->mesh.faces, RTC_BUILD_QUALITY_HIGH,
                               "building the triangle BVH");
  });
  return impl_->plain_scene->get();
}

double TriangleBvh::distance_to_face(const Vec3& p, std::uint32_t f) const {
  const Face& t = impl_->mesh.faces[f];
  const auto& pos = impl_->mesh.positions;
  return std::sqrt(squared_distance_to_triangle(p, pos[t[0]], pos[t[1]], pos[t[2]]));
}

ClosestPoint TriangleBvh::closest_point(const Vec3& p, double upper_bound) const {
  const Vec3 q = p - impl_->shift;  // the BVH's frame (the mesh's own but with outliers split off)
  // Float rounding of the coordinates, the BVH bounds and the query point is a few ulps (2^-24 relative)
  // of the largest coordinate involved; 1e-6 of it is a safe slack for the traversal radius.
  const double margin = 1e-6 * std::max({impl_->max_abs, std::abs(q.x()), std::abs(q.y()), std::abs(q.z()), 1e-30});
  const double inf = std::numeric_limits<double>::infinity();
  QueryState state{&impl_->mesh, impl_->spheres.data(), impl_->prim_face.empty() ? nullptr : impl_->prim_face.data(),
                   p, q, inf, inf, margin, {}};
  if (std::isfinite(upper_bound)) {
    // Slightly above the bound, so that the face the bound came from is still accepted.
    state.best2 = upper_bound * upper_bound * (1.0 + 1e-9) + 1e-300;
    state.best = std::sqrt(state.best2);
  }
  RTCPointQuery query;
  query.x = static_cast<float>(q.x());
  query.y = static_cast<float>(q.y());
  query.z = static_cast<float>(q.z());
  query.time = 0.0f;
  query.radius = std::isfinite(upper_bound) ? static_cast<float>(upper_bound * (1.0 + 1e-6) + margin)
                                            : std::numeric_limits<float>::infinity();
  RTCPointQueryContext context;
  rtcInitPointQueryContext(&context);
  rtcPointQuery(impl_->scene->get(), &query, &context, point_query_callback, &state);
  for (const std::uint32_t f : impl_->far_faces) (void)measure(state, f);
  if (state.result.found()) state.result.distance = state.best;
  return state.result;
}

}  // namespace gimforge
