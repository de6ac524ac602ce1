#include "core/model_rig.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <glm/gtc/matrix_inverse.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/mat3x3.hpp>

#include "core/model.hpp"
#include "core/request.hpp"

namespace umbra {

namespace {

template <class T>
std::size_t capacity_bytes(const std::vector<T>& v) {
  return v.capacity() * sizeof(T);
}

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

std::size_t ModelRig::bytes() const {
  std::size_t total = sizeof(ModelRig) + capacity_bytes(nodes) + capacity_bytes(order) + capacity_bytes(skins) +
                      capacity_bytes(primitives) + capacity_bytes(part_colors) + capacity_bytes(animations);
  for (const RigNode& n : nodes) total += capacity_bytes(n.weights);
  for (const RigSkin& s : skins) total += capacity_bytes(s.joints) + capacity_bytes(s.inverse_bind);
  for (const RigPrimitive& p : primitives) {
    total += capacity_bytes(p.positions) + capacity_bytes(p.normals) + capacity_bytes(p.indices) +
             capacity_bytes(p.joints) + capacity_bytes(p.weights) + capacity_bytes(p.target_positions) +
             capacity_bytes(p.target_normals);
    for (const auto& t : p.target_positions) total += capacity_bytes(t);
    for (const auto& t : p.target_normals) total += capacity_bytes(t);
  }
  for (const RigAnimation& a : animations) {
    total += a.name.capacity() + capacity_bytes(a.samplers) + capacity_bytes(a.channels);
    for (const RigSampler& s : a.samplers) total += capacity_bytes(s.times) + capacity_bytes(s.values);
  }
  return total;
}

std::vector<ModelAnimation> model_animations(const TriangleModel& model) {
  std::vector<ModelAnimation> list;
  if (!model.rig) return list;
  for (std::size_t a = 0; a < model.rig->animations.size(); ++a) {
    const RigAnimation& animation = model.rig->animations[a];
    list.push_back({a, animation.name, animation.duration_s, animation.channels.size()});
  }
  return list;
}

std::optional<std::size_t> find_animation(const ModelRig& rig, const std::string& name) {
  for (std::size_t a = 0; a < rig.animations.size(); ++a)
    if (rig.animations[a].name == name) return a;
  return std::nullopt;
}

double animation_time(double duration_s, double time, double speed, bool loop) {
  if (!(duration_s > 0.0)) return 0.0;
  const double t = time * speed;
  if (!loop) return std::clamp(t, 0.0, duration_s);
  const double wrapped = std::fmod(t, duration_s);
  return wrapped < 0.0 ? wrapped + duration_s : wrapped;
}

std::vector<double> sample(const RigSampler& s, double t, bool rotation) {
  const std::size_t keys = s.times.size(), w = s.width;
  const bool cubic = s.interpolation == RigInterpolation::CubicSpline;
  // Key k's value, and for cubic splines its tangents (glTF stores in-tangent,
  // value, out-tangent for each key).
  const auto value = [&](std::size_t k, std::size_t c) { return double(s.values[((cubic ? 3 * k + 1 : k) * w) + c]); };
  std::vector<double> out(w, 0.0);
  const auto normalize = [&] {
    if (!rotation || w != 4) return;
    const double length = std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3]);
    if (length > 0.0 && std::isfinite(length))
      for (double& x : out) x /= length;
    else
      out = {0.0, 0.0, 0.0, 1.0};
  };
  if (keys == 1 || t <= double(s.times.front()) || t >= double(s.times.back())) {
    const std::size_t k = keys == 1 || t <= double(s.times.front()) ? 0 : keys - 1;
    for (std::size_t c = 0; c < w; ++c) out[c] = value(k, c);
    normalize();
    return out;
  }
  // times[k] <= t < times[k + 1]
  const std::size_t k =
      std::size_t(std::upper_bound(s.times.begin(), s.times.end(), t, [](double x, float key) { return x < double(key); }) -
                  s.times.begin()) -
      1;
  const double t0 = s.times[k], t1 = s.times[k + 1], dt = t1 - t0;
  const double u = dt > 0.0 ? (t - t0) / dt : 0.0;
  switch (s.interpolation) {
    case RigInterpolation::Step:
      for (std::size_t c = 0; c < w; ++c) out[c] = value(k, c);
      break;
    case RigInterpolation::Linear:
      if (rotation && w == 4) {
        glm::dquat a(value(k, 3), value(k, 0), value(k, 1), value(k, 2));
        glm::dquat b(value(k + 1, 3), value(k + 1, 0), value(k + 1, 1), value(k + 1, 2));
        if (glm::dot(a, b) < 0.0) b = -b;  // the shorter way round
        const glm::dquat q = glm::slerp(a, b, u);
        out = {q.x, q.y, q.z, q.w};
      } else {
        for (std::size_t c = 0; c < w; ++c) out[c] = value(k, c) * (1.0 - u) + value(k + 1, c) * u;
      }
      break;
    case RigInterpolation::CubicSpline: {
      const double u2 = u * u, u3 = u2 * u;
      const double h00 = 2 * u3 - 3 * u2 + 1, h10 = u3 - 2 * u2 + u, h01 = -2 * u3 + 3 * u2, h11 = u3 - u2;
      for (std::size_t c = 0; c < w; ++c) {
        const double out_tangent = s.values[(3 * k + 2) * w + c], in_tangent = s.values[(3 * (k + 1)) * w + c];
        out[c] = h00 * value(k, c) + h10 * dt * out_tangent + h01 * value(k + 1, c) + h11 * dt * in_tangent;
      }
      break;
    }
  }
  normalize();
  return out;
}

namespace {

TriangleModel pose(const ModelRig& rig, const RigAnimation* anim, double t, const std::function<bool()>& stop) {
  const std::size_t n = rig.nodes.size();
  // Asked between primitives and every 64k vertices of a large one.
  std::size_t since_asked = 0;
  const auto ask = [&](std::size_t work) {
    since_asked += work;
    if (!stop || since_asked < 65536) return;
    since_asked = 0;
    if (stop()) throw PoseStopped{};
  };

  // 1. Each node's local transform: its channels' values, else its own.
  std::vector<glm::dvec3> translation(n), scale(n);
  std::vector<glm::dquat> rotation(n);
  std::vector<std::vector<float>> weights(n);
  for (std::size_t i = 0; i < n; ++i) {
    translation[i] = rig.nodes[i].translation;
    rotation[i] = rig.nodes[i].rotation;
    scale[i] = rig.nodes[i].scale;
    weights[i] = rig.nodes[i].weights;
  }
  for (const RigChannel& c : anim ? anim->channels : std::vector<RigChannel>{}) {
    const std::vector<double> v = sample(anim->samplers.at(c.sampler), t, c.path == RigPath::Rotation);
    switch (c.path) {
      case RigPath::Translation: translation[c.node] = {v[0], v[1], v[2]}; break;
      case RigPath::Rotation: rotation[c.node] = glm::dquat(v[3], v[0], v[1], v[2]); break;
      case RigPath::Scale: scale[c.node] = {v[0], v[1], v[2]}; break;
      case RigPath::Weights:
        weights[c.node].assign(weights[c.node].size(), 0.0f);
        for (std::size_t k = 0; k < std::min(v.size(), weights[c.node].size()); ++k) weights[c.node][k] = float(v[k]);
        break;
    }
  }

  // 2. World transforms, parents first.
  std::vector<glm::dmat4> world(n, glm::dmat4(1.0));
  for (const std::size_t i : rig.order) {
    const RigNode& node = rig.nodes[i];
    const glm::dmat4 local = node.matrix ? *node.matrix
                                         : glm::translate(glm::dmat4(1.0), translation[i]) *
                                               glm::dmat4(glm::mat3_cast(rotation[i])) *
                                               glm::scale(glm::dmat4(1.0), scale[i]);
    world[i] = node.parent >= 0 ? world[std::size_t(node.parent)] * local : local;
  }
  // Each skin's joint matrices.
  std::vector<std::vector<glm::dmat4>> joint_matrices(rig.skins.size());
  for (std::size_t s = 0; s < rig.skins.size(); ++s)
    for (std::size_t j = 0; j < rig.skins[s].joints.size(); ++j)
      joint_matrices[s].push_back(world[rig.skins[s].joints[j]] * rig.skins[s].inverse_bind[j]);

  // 3. Every primitive moved: morph targets, then its node's or its
  // joints' transform.
  TriangleModel model;
  model.parts.resize(rig.part_colors.size());
  for (std::size_t p = 0; p < model.parts.size(); ++p) model.parts[p].base_color = rig.part_colors[p];
  for (const RigPrimitive& prim : rig.primitives) {
    const std::size_t vertices = prim.positions.size();
    ask(vertices / 2);
    std::vector<glm::dvec3> positions(vertices), normals;
    for (std::size_t v = 0; v < vertices; ++v) positions[v] = prim.positions[v];
    if (!prim.normals.empty()) {
      normals.resize(vertices);
      for (std::size_t v = 0; v < vertices; ++v) normals[v] = prim.normals[v];
    }
    const std::vector<float>& w = weights[prim.node];
    for (std::size_t target = 0; target < prim.target_positions.size() && target < w.size(); ++target) {
      if (w[target] == 0.0f) continue;
      const double weight = w[target];
      if (!prim.target_positions[target].empty())
        for (std::size_t v = 0; v < vertices; ++v) positions[v] += weight * glm::dvec3(prim.target_positions[target][v]);
      if (!normals.empty() && target < prim.target_normals.size() && !prim.target_normals[target].empty())
        for (std::size_t v = 0; v < vertices; ++v) normals[v] += weight * glm::dvec3(prim.target_normals[target][v]);
    }

    std::vector<glm::vec3> out_positions(vertices), out_normals;
    bool normals_ok = !normals.empty();
    if (normals_ok) out_normals.resize(vertices);
    std::vector<std::uint32_t> indices = prim.indices;
    const auto place = [&](std::size_t v, const glm::dmat4& m) {
      out_positions[v] = glm::vec3(glm::dvec3(m * glm::dvec4(positions[v], 1.0)));
      if (!normals_ok) return;
      const glm::dvec3 turned = glm::inverseTranspose(glm::dmat3(m)) * normals[v];
      const double length = glm::length(turned);
      if (length > 0.0 && std::isfinite(length))
        out_normals[v] = glm::vec3(turned / length);
      else
        normals_ok = false;
    };
    if (prim.skin >= 0) {
      const std::vector<glm::dmat4>& joints = joint_matrices[std::size_t(prim.skin)];
      std::vector<bool> mirrored(vertices, false);
      for (std::size_t v = 0; v < vertices; ++v) {
        if ((v & 0xffff) == 0xffff) ask(65536);
        glm::dmat4 m(0.0);
        double total = 0.0;
        for (int k = 0; k < 4; ++k) {
          const double weight = prim.weights[v][k];
          if (weight == 0.0) continue;
          m += weight * joints[prim.joints[v][k]];
          total += weight;
        }
        if (!(total > 0.0)) m = world[prim.node];  // no weight at all: where its node puts it
        mirrored[v] = glm::determinant(glm::dmat3(m)) < 0.0;
        place(v, m);
      }
      for (std::size_t i = 0; i + 2 < indices.size(); i += 3)
        if (mirrored[indices[i]]) std::swap(indices[i + 1], indices[i + 2]);
    } else {
      const glm::dmat4& m = world[prim.node];
      for (std::size_t v = 0; v < vertices; ++v) place(v, m);
      // A mirroring transform turns counter-clockwise into clockwise.
      if (glm::determinant(glm::dmat3(m)) < 0.0)
        for (std::size_t i = 0; i + 2 < indices.size(); i += 3) std::swap(indices[i + 1], indices[i + 2]);
    }
    for (const glm::vec3& p : out_positions)
      if (!finite(p)) throw std::domain_error("a posed position is not finite (too large for 32-bit floats)");
    if (!normals_ok) out_normals = area_weighted_normals(out_positions, indices);

    model.parts.at(prim.part).append(out_positions, out_normals, indices);
  }
  finish_model(model);
  return model;
}

}  // namespace

TriangleModel pose_model(const ModelRig& rig, std::size_t animation, double t, const std::function<bool()>& stop) {
  return pose(rig, &rig.animations.at(animation), t, stop);
}

TriangleModel pose_rest(const ModelRig& rig) { return pose(rig, nullptr, 0.0, nullptr); }

bool rig_deforms(const ModelRig& rig) {
  for (const RigPrimitive& p : rig.primitives) {
    if (p.skin >= 0) return true;
    const std::vector<float>& w = rig.nodes[p.node].weights;
    for (std::size_t t = 0; t < std::min(w.size(), p.target_positions.size()); ++t)
      if (w[t] != 0.0f && !p.target_positions[t].empty()) return true;
  }
  return false;
}

}  // namespace umbra
