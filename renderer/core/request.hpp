// The typed render request: what a client asked for, with every default applied.
//
// This is the boundary between the HTTP server (which builds it from JSON, see
// server/request_parser.hpp) and the renderer (which draws it). It holds no GL
// and no JSON. Units and ranges below are the ones docs/api.md fixes; the
// parser enforces them, so the renderer may rely on them.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/shapes/shape_list.hpp"

namespace umbra {

struct TriangleModel;  // model.hpp

/// One object of a scene, in world units: an analytic primitive or an
/// instance of a triangle model (mesh_instance.hpp).
struct SceneObject {
  // One value per shape kind (core/shapes/shape_list.hpp).
#define UMBRA_SHAPE_TYPE(value, row) value,
  enum class Type { UMBRA_SHAPE_KINDS(UMBRA_SHAPE_TYPE) };
#undef UMBRA_SHAPE_TYPE
  Type type = Type::Box;
  /// Centre of the primitive; a mesh's position (where its model-space
  /// origin goes).
  glm::dvec3 center{0.0};
  /// Plane: (sx, 0, sz), a horizontal rectangle facing +Y. Box: (sx, sy, sz),
  /// full edge lengths. Sphere: unused. Every used component > 0.
  glm::dvec3 size{1.0};
  /// Sphere radius, > 0. Unused otherwise.
  double radius = 0.5;
  /// Box rotation about its own vertical axis, degrees, counter-clockwise seen
  /// from +Y (right-handed). Boxes only.
  double rotation_y_deg = 0.0;
  /// Linear RGB albedo, each in [0, 1]. A mesh uses it only when
  /// `mesh_color_override` is set; otherwise its parts' base colours.
  glm::dvec3 color{0.8};

  // Meshes only. World = translate(center) * Rz * Ry * Rx * scale(mesh_scale)
  // * model space: rotations right-handed, applied X, then Y, then Z.
  /// The model, shared with the store (never null for a mesh).
  std::shared_ptr<const TriangleModel> model;
  /// The store's id of `model` ("sha256:..."): what identifies its geometry.
  std::string model_id;
  glm::dvec3 rotation_deg{0.0};
  /// Each component > 0.
  glm::dvec3 mesh_scale{1.0};
  bool mesh_color_override = false;
  /// Which of the model's animations poses it at the request's `time`
  /// (model_rig.hpp), as the request named it; none: its rest pose.
  struct Animation {
    std::size_t index = 0;  ///< in the model's rig, resolved from a name or index
    std::string name;       ///< as sent, if by name
    double speed = 1.0;     ///< animation seconds per request second; negative plays backwards
    bool loop = true;       ///< wrap past the end; else hold the last (or first) pose
  };
  std::optional<Animation> animation;
  /// "" for the rest pose; else which pose `model` is ("animation 0 at
  /// 1.25 s"): with model_id, what identifies the geometry drawn.
  std::string pose;
};

/// One of a model's animations, as a mesh object's `"animation"` names it
/// and GET /api/models lists it.
struct ModelAnimation {
  std::size_t index = 0;
  std::string name;  ///< as the file names it; may be empty
  double duration_s = 0.0;
  std::size_t channels = 0;
};
/// The model's animations in the file's order (none for a model without
/// them): what a request may name, from core/model_rig.cpp.
std::vector<ModelAnimation> model_animations(const TriangleModel& model);

struct Scene {
  /// The built-in scene's name, or empty for a custom scene.
  std::string name;
  std::vector<SceneObject> objects;
};

/// The viewer. Position != target; up is non-zero (it may be parallel to the
/// view direction: the renderer then picks a stable substitute).
struct Camera {
  glm::dvec3 position{0.0, 3.0, 6.0};
  glm::dvec3 target{0.0};
  glm::dvec3 up{0.0, 1.0, 0.0};
  /// Vertical field of view, degrees, in (0, 180).
  double fov_y_deg = 45.0;
  /// Clip distances, world units, 0 < near < far.
  double near_plane = 0.1;
  double far_plane = 100.0;
};

enum class LightProjection {
  /// A directional light: parallel rays travelling position -> target.
  Orthographic,
  /// A point light at `position`, its shadow frustum looking at `target`.
  Perspective,
};

/// A sun light: the light comes from the sun's apparent direction at a place
/// and instant (sun_position.hpp), instead of orbiting. The scene's -Z axis
/// points north, +X east, +Y up, before `north_deg` turns them.
struct SunClock {
  /// Degrees, [-90, 90], north positive.
  double latitude_deg = 0.0;
  /// Degrees, [-180, 180], east positive.
  double longitude_deg = 0.0;
  /// The instant at time 0: seconds since 1970-01-01T00:00:00Z (UTC, taken
  /// as UT1), from the API's RFC 3339 "utc" text; years 0001..5000.
  /// The request's `time` advances this clock, in seconds.
  double utc_unix_s = 0.0;
  /// Where north is in the scene: -Z turned clockwise seen from above by
  /// this many degrees, [-360, 360]. Default 0 (north is -Z).
  double north_deg = 0.0;
};

struct Light {
  /// For an orthographic light only the direction position -> target matters.
  /// position != target. Before rendering, `position` is orbited by `time`
  /// (light_at in light_math.hpp); with a `sun`, only its distance from the
  /// target is kept.
  glm::dvec3 position{-2.0, 4.0, -1.0};
  glm::dvec3 target{0.0};
  /// Linear RGB, each in [0, 1].
  glm::dvec3 color{1.0};
  /// Fraction of the light that arrives as unshadowed ambient, [0, 1].
  double ambient = 0.3;
  LightProjection projection = LightProjection::Orthographic;
  /// Full vertical (= horizontal) field of view of a perspective light's
  /// shadow frustum, degrees, in (0, 180). Used with fit "fixed" only.
  double fov_y_deg = 90.0;
  /// 0: an ideal light, hard shadows. > 0: an area light — orthographic: the
  /// angular diameter in degrees, (0, 90]; perspective: the radius, world units.
  double size = 0.0;
  /// Orbit speed of the light about +Y through `target`, degrees per second.
  /// Unused with a `sun`.
  double orbit_deg_per_s = 20.0;
  /// Set: a sun light (always orthographic), placed by the sun's position at
  /// sun->utc_unix_s + time; below the horizon only ambient light arrives.
  std::optional<SunClock> sun;
};

enum class ShadowFilter {
  /// One nearest-texel depth comparison: aliased, exact-or-nothing.
  Hard,
  /// Percentage-closer filtering over (2r+1)^2 bilinear comparisons.
  Pcf,
  /// Percentage-closer soft shadows: penumbra width from light.size and the
  /// average blocker distance.
  Pcss,
  /// Certified hard shadows (a light of no size only): each pixel the
  /// shadow maps prove lit or shadowed takes that answer, every other one
  /// is ray cast, so the shadow term equals the exact reference's
  /// (docs/certified-shadows.md).
  Exact,
};

enum class CullMode { Front, Back, None };

enum class FrustumFit {
  /// Light frustum, near and far fitted to the scene (see light_math.hpp).
  Scene,
  /// ortho_half_size / light.fov_y_deg / near / far exactly as given (the seeds).
  Fixed,
};

/// Depth bias. `automatic` (the API's "auto") derives it from the shadow-map
/// texel's world size at each fragment (normal offset plus receiver-plane
/// slope), so it holds at every scene scale and map size.
/// Otherwise the seeds' formula with the client's numbers:
///   depth bias = max(slope * (1 - N.L), constant)   [light depth-buffer units, 0..1]
///   receiver moved along its normal by normal_offset  [shadow-map texels]
struct DepthBias {
  bool automatic = true;
  double constant = 0.005;     ///< >= 0, <= 1
  double slope = 0.05;         ///< >= 0, <= 1
  double normal_offset = 0.0;  ///< >= 0, <= 64 texels
};

/// Shadow settings; every field documented with unit, range and default.
struct ShadowSettings {
  /// false: no shadow pass at all, every surface facing the light is lit.
  bool enabled = true;
  /// Shadow map width = height, texels, 64..8192. Default 2048.
  int map_size = 2048;
  ShadowFilter filter = ShadowFilter::Pcf;
  /// PCF kernel half-width r: (2r+1)^2 taps, 0..8. Default 1.
  int pcf_radius = 1;
  DepthBias bias{};
  /// Faces culled in the shadow pass, applied to closed meshes (boxes,
  /// spheres, closed models). Open meshes (planes, models that are not
  /// closed: TriangleModel::closed) are always drawn two-sided there, since
  /// culling either side of a one-sided plane would drop it as a caster.
  CullMode cull = CullMode::Front;
  FrustumFit fit = FrustumFit::Scene;
  /// Fit "scene", orthographic light only: how many cascades split the
  /// camera's view depth, each with its own map_size^2 layer fitted to what
  /// the camera sees in its depth range. 0 ("auto"): as few as give the
  /// nearest visible receivers about one shadow texel per pixel, 1..4.
  /// (A perspective light picks one cone or six cube faces by itself.)
  int cascades = 0;
  /// Fixed fit only: orthographic half-extent (world units, > 0) and the
  /// light's near/far planes (world units from the light, 0 < near < far for a
  /// perspective light; near < far for an orthographic one).
  double ortho_half_size = 10.0;
  double near_plane = 1.0;
  double far_plane = 7.5;
};

enum class Output { Color, Depth, Shadow, Exact, Error };

struct RenderRequest {
  /// Output image size, pixels, 16..4096 each. Default 960 x 540.
  int width = 960;
  int height = 540;
  Scene scene;
  Camera camera;
  Light light;
  /// Animation time, seconds. The light position is rotated about +Y through
  /// light.target by time * light.orbit_deg_per_s degrees; a sun light's
  /// clock is advanced by `time` seconds.
  double time = 0.0;
  ShadowSettings shadow;
  Output output = Output::Color;
  /// Bits per sample of the "depth" output's grey image: 8 (256 levels, the
  /// default clients rely on) or 16 (65536 levels, for reading depths; the
  /// same mapping, near = black). Default 8. No effect on other outputs.
  int depth_bits = 8;
};

const char* to_string(Output output);
const char* to_string(LightProjection projection);

}  // namespace umbra
