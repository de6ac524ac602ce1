// Animated models: what a glTF file says moves (its nodes' translation,
// rotation and scale channels, skins, morph targets), kept beside the
// model's rest-pose triangles, and the model posed at an instant of one of
// its animations. The loader fills a rig (assets/gltf_loader.cpp) only for
// a file that has animations; a request's mesh object names one
// (`"animation"`, docs/api.md) and is drawn, ray cast and priced in that
// pose. Pure CPU code, no GL: unit tested in tests/test_model_rig.cpp.
//
// The rules are glTF 2.0's (§3.7 and §3.11): a node's local transform is
// T * R * S, each taken from its channel when the animation has one, else
// from the node; a skinned primitive's vertices are moved by
// sum_j w_j * world(joint_j) * inverseBind_j (the skinned node's own
// transform ignored); morph targets add sum_i weight_i * target_i to the
// positions and normals before skinning.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

namespace umbra {

struct TriangleModel;  // model.hpp

/// Morph targets one primitive may have (the loader refuses more, 422).
constexpr std::size_t kMaxMorphTargets = 64;
/// Animations one model may have (each is listed by GET /api/models).
constexpr std::size_t kMaxAnimations = 1024;
/// Keyframe numbers (times and values, floats) one model's animations may
/// hold in all: 16 MiB of them.
constexpr std::size_t kMaxAnimationFloats = std::size_t(4) << 20;

struct RigNode {
  int parent = -1;  ///< index in ModelRig::nodes; -1 for a root
  glm::dvec3 translation{0.0};
  glm::dquat rotation{1.0, 0.0, 0.0, 0.0};
  glm::dvec3 scale{1.0};
  /// A node given by a matrix: glTF does not let an animation move it.
  std::optional<glm::dmat4> matrix;
  /// Its morph weights at rest (node.weights, else its mesh's weights, else
  /// zeros): one per morph target of its mesh.
  std::vector<float> weights;
};

enum class RigPath { Translation, Rotation, Scale, Weights };
enum class RigInterpolation { Linear, Step, CubicSpline };

struct RigSampler {
  std::vector<float> times;   ///< seconds, increasing, at least one
  /// `width` floats a key (three times as many for CubicSpline: in-tangent,
  /// value, out-tangent).
  std::vector<float> values;
  std::size_t width = 0;  ///< 3 (translation, scale), 4 (rotation xyzw), targets (weights)
  RigInterpolation interpolation = RigInterpolation::Linear;
};

struct RigChannel {
  std::size_t node = 0;
  RigPath path = RigPath::Translation;
  std::size_t sampler = 0;
};

struct RigAnimation {
  std::string name;  ///< may be empty (then it is named by its index)
  std::vector<RigSampler> samplers;
  std::vector<RigChannel> channels;
  double duration_s = 0.0;  ///< the latest key time of its samplers
};

struct RigSkin {
  std::vector<std::size_t> joints;        ///< nodes
  std::vector<glm::dmat4> inverse_bind;   ///< one per joint (identity when the file gives none)
};

/// One triangle primitive as one node instances it, in its mesh's space.
struct RigPrimitive {
  std::size_t node = 0;
  int skin = -1;          ///< index in ModelRig::skins, or -1
  std::size_t part = 0;   ///< which of the model's parts (base colours) it joins
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;        ///< one per position, or none (then made from the triangles)
  std::vector<std::uint32_t> indices;    ///< counter-clockwise, three a triangle
  std::vector<std::array<std::uint16_t, 4>> joints;  ///< per vertex when skinned: indices into the skin's joints
  std::vector<glm::vec4> weights;                    ///< per vertex when skinned
  /// Per morph target: position and normal offsets, each one per vertex or
  /// empty (the target does not move it).
  std::vector<std::vector<glm::vec3>> target_positions, target_normals;
};

struct ModelRig {
  std::vector<RigNode> nodes;
  /// The nodes the scene reaches, parents before children.
  std::vector<std::size_t> order;
  std::vector<RigSkin> skins;
  std::vector<RigPrimitive> primitives;
  std::vector<glm::vec3> part_colors;  ///< the posed model's parts, in order
  std::vector<RigAnimation> animations;

  /// What it holds in memory (vectors' capacities): counted with its model.
  std::size_t bytes() const;
};

/// The animation named `name` (the first of that name), or none.
std::optional<std::size_t> find_animation(const ModelRig& rig, const std::string& name);

/// Where in an animation of `duration_s` seconds a request's `time` falls:
/// time * speed, wrapped into [0, duration) when `loop`, else held within
/// [0, duration]. 0 for an animation of no length.
double animation_time(double duration_s, double time, double speed, bool loop);

/// One sampler's value at `t` seconds (held at the first and last keys):
/// `width` numbers. Rotations are normalized quaternions (x, y, z, w),
/// spherically interpolated the shorter way.
std::vector<double> sample(const RigSampler& sampler, double t, bool rotation);

/// Thrown by pose_model when its `stop` answered true.
struct PoseStopped {};

/// The model as animation `animation` poses it at its own time `t`
/// (seconds): every primitive's triangles moved, normals turned with them,
/// parts as the rest model's, finished (bounds, closedness...). Throws
/// std::out_of_range for an animation the rig does not have,
/// std::domain_error for a pose that is not finite, and PoseStopped once
/// `stop` (if given; asked about every 64k vertices) answers true.
TriangleModel pose_model(const ModelRig& rig, std::size_t animation, double t,
                         const std::function<bool()>& stop = nullptr);

/// The model at rest: every node as the file places it, skins and morph
/// targets applied (their default weights). What a skinned or morphed
/// model looks like before any animation moves it.
TriangleModel pose_rest(const ModelRig& rig);

/// Whether the rest pose needs the rig: a primitive is skinned, or has
/// morph targets its node weighs.
bool rig_deforms(const ModelRig& rig);

}  // namespace umbra
