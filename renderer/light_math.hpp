// Camera and light-space matrices: pure math in double precision, no GL.
//
// Conventions follow GLM (right-handed, view looks down -Z, clip z in [-w, w]).
// Everything here is unit tested without a GPU (tests/test_light_math.cpp).
#pragma once

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "request.hpp"
#include "scene.hpp"

namespace umbra {

/// The light position after `time` seconds of orbit: rotated about the
/// vertical (+Y) axis through light.target by time * orbit_deg_per_s degrees,
/// counter-clockwise seen from above.
glm::dvec3 orbit_light_position(const Light& light, double time);

/// glm::lookAt, except that when `up` is (nearly) parallel to the view
/// direction — a light straight above its target, a camera looking straight
/// down with up = +Y — it substitutes a stable axis instead of producing NaNs:
/// -Z when looking down, +Z when looking up, +Y otherwise.
/// Precondition: eye != target, up != 0.
glm::dmat4 stable_look_at(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up);

/// The light's shadow frustum.
struct LightFrustum {
  bool perspective = false;
  glm::dmat4 view{1.0};
  glm::dmat4 projection{1.0};
  /// Near and far planes, world units along the light's view axis. An
  /// orthographic near plane may be negative (it is just a slab).
  double near_plane = 1.0;
  double far_plane = 7.5;
  /// Orthographic: world size of one shadow-map texel (the larger of x, y).
  /// Perspective: world size of one texel per unit of distance along the axis.
  double texel_size = 0.0;
  /// Light position (orbited) and unit direction of travel of its light
  /// (position -> target).
  glm::dvec3 position{0.0};
  glm::dvec3 direction{0.0, -1.0, 0.0};

  glm::dmat4 view_projection() const { return projection * view; }
};

/// The largest field of view a fitted perspective light may use: beyond it
/// the edge texels stretch too far to be worth having (degrees).
inline constexpr double kMaxFittedLightFovDeg = 150.0;

/// Builds the light's frustum for the request (light already orbited by
/// request.time). fit "fixed": the seeds' ortho(+-h, +-h, near, far) or
/// perspective(light.fov_y_deg, 1, near, far). fit "scene": tight around the
/// bounds of every object (orthographic: the light-space box of the objects'
/// corners; perspective: the narrowest square cone, nearest and farthest
/// depth of the objects' boxes).
LightFrustum light_frustum(const RenderRequest& request);

/// The camera's view and projection for an image of width x height.
struct CameraMatrices {
  glm::dmat4 view{1.0};
  glm::dmat4 projection{1.0};
};
CameraMatrices camera_matrices(const Camera& camera, int width, int height);

}  // namespace umbra
