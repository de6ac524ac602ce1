// Camera and light-space matrices: pure math in double precision, no GL.
//
// Conventions follow GLM (right-handed, view looks down -Z, clip z in [-w, w]).
// Everything here is unit tested without a GPU (tests/test_light_math.cpp).
#pragma once

#include <algorithm>
#include <optional>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "core/request.hpp"
#include "core/scene.hpp"
#include "core/sun_position.hpp"

namespace umbra {

/// The light position after `time` seconds of orbit: rotated about the
/// vertical (+Y) axis through light.target by time * orbit_deg_per_s degrees,
/// counter-clockwise seen from above.
glm::dvec3 orbit_light_position(const Light& light, double time);

/// The unit vector from the scene towards a sun at `azimuth_deg` (clockwise
/// from north) and `elevation_deg` (above the horizon), in scene coordinates:
/// +Y up, north along -Z turned clockwise seen from above by `north_deg`
/// (so with north_deg 0, east is +X and the noon sun of the northern
/// mid-latitudes stands towards +Z).
glm::dvec3 sun_direction(double azimuth_deg, double elevation_deg, double north_deg);

/// Where a light stands at a moment of the animation.
struct LightState {
  glm::dvec3 position{0.0};
  /// false: a sun below the horizon. No direct light arrives anywhere
  /// (visibility 0, ambient only), in the rendered frame and the exact
  /// reference alike.
  bool direct = true;
  /// A sun light's apparent position at that moment (the Umbra-Sun header).
  std::optional<SunAngles> sun;
};

/// The one update function for every kind of light, each kind placing
/// itself (its row's `place`, core/lights/light_kind.hpp):
/// - orbiting (no light.sun): orbit_light_position(light, time);
/// - a sun: target + sun_direction x |position - target|, the sun's position
///   at sun.utc_unix_s + time seconds (solar_position, NREL SPA); its direct
///   light is off while its apparent elevation is below 0.
LightState light_at(const Light& light, double time);

/// A directional area light's angular radius, as its tangent: tan(size / 2),
/// size being the disc's angular diameter in degrees. The shader's penumbra
/// and the exact reference's disc both use this one value.
double sun_disc_tan_radius(const Light& light);

/// How far (world units) a float view matrix relative to the mesh origin
/// (the GL's) may move a corner whose coordinates relative to that origin
/// reach `extent` (largest |coordinate|): about 1e-6 of the coordinates
/// involved, `translation` (the length of the matrix's translation) among
/// them, as seen_here (scene.frag) bounds the camera's. Filter "exact"'s
/// maps and certificate take it in (docs/certified-shadows.md).
inline double light_view_rounding(double extent, double translation) {
  return 1e-6 * (1.7320508075688772 * extent + translation);
}

/// The world size of one texel of filter "exact"'s conservative maps, each
/// `coarse_texels` texels of a layer whose texels are `texel_size` (a point
/// light's per unit of distance): a directional light's smaller side; a
/// point light's at clip w `nearest_w`, off its axis where it is smallest
/// (over 1 + 2 tan_half). The plan, the maps and their folds measure
/// swell and rounding in it.
inline double certified_texel_world(bool perspective, const glm::dvec2& texel_size, double tan_half,
                                    double coarse_texels, double nearest_w) {
  return perspective ? texel_size.x * nearest_w * coarse_texels / (1.0 + 2.0 * tan_half)
                     : std::min(texel_size.x, texel_size.y) * coarse_texels;
}

/// glm::lookAt, except that when `up` is (nearly) parallel to the view
/// direction — a light straight above its target, a camera looking straight
/// down with up = +Y — it substitutes a stable axis instead of producing NaNs:
/// -Z when looking down, +Z when looking up, +Y otherwise.
/// Precondition: eye != target, up != 0.
glm::dmat4 stable_look_at(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up);

/// The view of cube face `face` (0..5: +X, -X, +Y, -Y, +Z, -Z) of a point
/// light at `position`: stable_look_at along the face's axis with up +Y
/// (+Z, -Z for the +Y, -Y faces). With s = +1 on the even faces and -1 on
/// the odd ones, a point at d = p - position is at eye
///   (s d.z, d.y, -s d.x) on +-X,  (d.x, s d.z, -s d.y) on +-Y,
///   (-s d.x, d.y, -s d.z) on +-Z:
/// a signed permutation, which scene.frag (LIGHT_CUBE) builds from the
/// face's axis and sign instead of selecting a matrix per pixel.
glm::dmat4 cube_face_view(const glm::dvec3& position, int face);

/// The camera's view and projection for an image of width x height.
struct CameraMatrices {
  glm::dmat4 view{1.0};
  glm::dmat4 projection{1.0};
};
CameraMatrices camera_matrices(const Camera& camera, int width, int height);

/// The rectangle, in normalised device x and y (-1..1 across the image),
/// that holds the box's 8 corners projected by `view_projection`, not
/// clipped to the image; nullopt where a corner lies at or behind clip w =
/// `nearest_w` (its projection is unbounded there).
struct ScreenBounds {
  glm::dvec2 low, high;
};
std::optional<ScreenBounds> screen_bounds_of(const Aabb& box, const glm::dmat4& view_projection, double nearest_w);

/// The pixels of a width x height image that the box's projection by the
/// camera can cover: the area of its bounding rectangle, clipped to the
/// image; the whole image if the box reaches behind the camera's eye.
double screen_pixels_of(const Aabb& box, const Camera& camera, int width, int height);

/// One flag per scene object: whether the main pass draws it in two parts,
/// split where its points may face the light (ShadowRenderer::
/// run_display_pass). Only closed meshes are split, and only those that
/// cover at least 4 pixels of the image per triangle: the split draws each
/// triangle twice, which on llvmpipe costs about what the shadow lookup of
/// one pixel does, so a fine mesh seen small (a 9,000-triangle sphere far
/// off) would cost more than the pixels it spares.
std::vector<bool> objects_split_by_the_light(const Mesh& mesh, const Camera& camera, int width, int height);

/// The camera's projection with reversed depth for a clip volume of z in
/// [0, w] (glClipControl's GL_ZERO_TO_ONE): window depth 1 at the near
/// plane, 0 at the far plane. With a floating-point depth buffer this keeps
/// depth distinct at any ratio of far to near (near 1e-9, far 1e9), where
/// the usual mapping rounds everything past a few near distances to 1 and
/// draws nothing. Only the main pass draws with it; the light math keeps
/// camera_matrices' conventional projection.
glm::dmat4 reversed_depth_projection(const Camera& camera, int width, int height);

/// One view of the light, rendered into one layer of the shadow map array.
struct ShadowView {
  glm::dmat4 view{1.0};
  glm::dmat4 projection{1.0};
  /// Near and far planes, world units along the view's axis. An orthographic
  /// near plane may be negative (it is just a slab).
  double near_plane = 1.0;
  double far_plane = 7.5;
  /// Orthographic: world size of one texel along light x and y.
  /// Perspective: world size of one texel per unit of distance (x = y).
  glm::dvec2 texel_size{0.0};
  /// Perspective: tangent of half the field of view; 0 when orthographic.
  double tan_half = 0.0;
  /// No object reaches into this view, so its pass has nothing to draw.
  bool empty = false;

  glm::dmat4 view_projection() const { return projection * view; }
};

/// How the light's shadow is laid out in the map array.
enum class ShadowLayout {
  Single,    ///< one view (fit "fixed", or one cone / one box holds everything)
  Cascades,  ///< orthographic light: 2..4 views, nearest camera depths first
  Cube,      ///< point light: six 90-degree (plus a kernel margin) faces
};

/// Everything the shadow and main passes need to know about the light.
struct ShadowPlan {
  bool perspective = false;
  /// light_at's `direct`: false, a sun below the horizon, whose frame needs
  /// no shadow map (only a depth preview draws one).
  bool direct_light = true;
  /// Light position (orbited) and unit direction of travel of its light
  /// (position -> target).
  glm::dvec3 position{0.0};
  glm::dvec3 direction{0.0, -1.0, 0.0};
  ShadowLayout layout = ShadowLayout::Single;
  /// Texels per side of each layer: shadow.map_size, unless the layers
  /// together would exceed kMaxShadowTexels (then the largest that fits).
  int layer_size = 2048;
  /// One per layer. The main pass uses, for each point, the first view whose
  /// map holds the point and its filter kernel.
  std::vector<ShadowView> views;
};

/// The most texels all layers together may hold: four 8192^2 maps (1 GiB of
/// 32-bit depth). Six cube faces at map_size 8192 are made smaller to fit.
inline constexpr double kMaxShadowTexels = 4.0 * 8192.0 * 8192.0;
/// The widest single cone a fitted point light uses (degrees); wider than
/// this, six cube faces spend the texels better than one stretched cone.
inline constexpr double kMaxFittedLightFovDeg = 120.0;
inline constexpr int kMaxCascades = 4;

/// Texels a filter reads around a point's own texel: the margin by which a
/// view must hold a point for the main pass to use it.
int filter_reach_texels(const ShadowSettings& shadow);

/// Texels a filter reads around a point's own texel, at most: the margin
/// around the casters that the shadow pass clears (PCSS's filter reaches
/// further than its blocker search).
int filter_read_texels(const ShadowSettings& shadow);

/// A rectangle of a layer, in texel units ([0, layer_size] per axis, as the
/// main pass addresses the map); empty unless min < max on both axes.
struct TexelRect {
  glm::dvec2 min{0.0};
  glm::dvec2 max{0.0};
  bool empty() const { return !(min.x < max.x && min.y < max.y); }
};

/// The part of `view`'s layer (layer_size^2 texels) that objects within
/// `casters` (world bounds) can cover: the bounding rectangle of their
/// projected corners (of the part inside the view's frustum, for a box that
/// reaches past the layer's sides or behind a perspective view's eye), one
/// texel wider on each side for rounding, clamped to the layer. Empty if
/// there is no caster or none reaches into the view.
TexelRect caster_texels(const ShadowView& view, int layer_size, const std::vector<Aabb>& casters);

/// Where each object reaches into each view's layer, found once per frame
/// for all who ask: the shadow pass (which layers to clear, which objects
/// to draw into each), the main pass (which points may be shadowed at all)
/// and the floor's cells (where they must look up the map).
struct CasterTexels {
  /// [view][object]: caster_texels of that object's bounds alone; empty for
  /// an object the shadow pass leaves out, and throughout an empty view.
  std::vector<std::vector<TexelRect>> by_object;
  /// [view]: the bounding rectangle of its row, which is caster_texels of
  /// all drawn objects at once (rounding outward commutes with the union).
  std::vector<TexelRect> by_view;
};
/// `bounds` and `drawn`: one per object (drawn: whether the shadow pass
/// draws it).
CasterTexels caster_texels_by_view(const ShadowPlan& plan, const std::vector<Aabb>& bounds,
                                   const std::vector<bool>& drawn);

/// Takes each `candidates` object out of every cascade after the first
/// that it shadows nothing in, and recomputes by_view. The main pass looks a
/// point up in the first cascade that holds it with the filter's reach to
/// spare (scene.frag's choose_view), so cascade k reads an object's texels
/// only for points that no earlier cascade holds. The points an object can
/// darken through cascade k lie within the filter's read
/// (filter_read_texels(shadow)) of its light-space rectangle there,
/// farther from the light than its nearest point, and inside one of the
/// scene's `bounds`. Where each such piece of every box lies in one earlier
/// cascade with the read to spare (at least the reach of any filter that
/// reads no further, so a map drawn this way serves any frame whose filter
/// reads no further), cascade k need not hold the object. A
/// 100,000-triangle teapot that the first of two cascades holds whole is
/// then drawn once, not twice. Only for ShadowLayout::Cascades, whose views
/// share one light eye space, and only with the automatic bias: the seeds'
/// bias looks a point up beside itself, up to normal_offset texels along
/// its normal (a frame with it must not reuse a map drawn with drops).
/// Returns whether anything was taken out.
bool drop_casters_held_by_earlier_cascades(const ShadowPlan& plan, const std::vector<Aabb>& bounds,
                                           const std::vector<bool>& candidates, const ShadowSettings& shadow,
                                           CasterTexels& table);

/// Plans the light's views for `request` (light placed by light_at at request.time).
///
/// fit "fixed": the seeds' single ortho(+-h, +-h, near, far) or
/// perspective(light.fov_y_deg, 1, near, far).
///
/// fit "scene", orthographic light: fitted to what the camera sees. The
/// camera frustum is cut into `cascades` depth ranges (auto: as few as give
/// the nearest visible receiver about one texel per pixel); each range's
/// intersection with the objects' bounds gives the receivers that matter,
/// their light-space rectangle gives the view's x/y, and its near plane is
/// pulled towards the light to hold every caster over that rectangle. The
/// rectangle's width is quantised and its origin snapped to whole texels, so
/// shadows do not shimmer as the camera moves.
///
/// fit "scene", perspective light: the narrowest cone around all objects if
/// it is at most kMaxFittedLightFovDeg wide, otherwise six cube faces; near
/// and far from the objects' distances to the light.
ShadowPlan plan_shadow(const RenderRequest& request);

/// True if a shadow map rendered for `have` serves a frame that planned
/// `want` at least as well: same light and layout, and each of have's views
/// holds want's view (orthographic: its rectangle and depth range contain
/// want's, with texels no larger; perspective: identical). The renderer then
/// keeps the map it has and draws with `have` instead of a new shadow pass.
/// Both plans must be for the same scene and cull mode.
bool plan_covers(const ShadowPlan& have, const ShadowPlan& want);

/// Whether `plane` can shadow any other object of its scene under the light
/// of `plan`. A horizontal plane only hides what lies beyond it from the
/// light; a floor under a scene lit from above hides nothing, and drawing
/// it into the map would fill every layer with texels that no receiver is
/// ever darker for (the receiver-plane test keeps the floor from shadowing
/// itself, and the cap at the receiver's own depth keeps it from shadowing
/// the objects that stand on it). So the shadow pass leaves such a plane
/// out. Edge-on, the plane covers no texel and hides nothing either.
bool plane_can_shadow(const PlaneRange& plane, const ShadowPlan& plan);

/// The vertices of the convex intersection of a frustum (given by its
/// view-projection matrix, clip z in [-w, w]) and a box; empty if they do not
/// meet. Exposed for tests.
std::vector<glm::dvec3> frustum_box_intersection(const glm::dmat4& view_projection, const Aabb& box);

}  // namespace umbra
