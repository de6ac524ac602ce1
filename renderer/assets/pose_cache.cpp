#include "assets/pose_cache.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <new>
#include <set>

#include "core/mesh_instance.hpp"
#include "core/model_rig.hpp"

namespace umbra {

namespace {

std::string mib(std::uint64_t bytes) { return std::to_string((bytes + (1 << 20) - 1) >> 20) + " MiB"; }

// The time as its bits (every distinct double a distinct pose) and as a
// reader sees it.
std::string time_text(double t) {
  char text[64];
  std::snprintf(text, sizeof text, "%.17g", t);
  return text;
}

// A pose's identity: the model (by address, checked against the entry's
// source), the animation and the time's bits (every distinct double a
// distinct pose).
std::string pose_key(const std::shared_ptr<const TriangleModel>& model, std::size_t animation, double t) {
  char address[32];
  std::snprintf(address, sizeof address, "%p", static_cast<const void*>(model.get()));
  std::uint64_t bits = 0;
  std::memcpy(&bits, &t, sizeof bits);
  return std::string(address) + "/" + std::to_string(animation) + "/" + std::to_string(bits);
}

// What a pose will hold: the rest model's triangles and vertices, less its
// rig (a pose has none).
std::uint64_t pose_bytes(const TriangleModel& model) { return model.bytes() - model.rig->bytes(); }

}  // namespace

std::shared_ptr<const TriangleModel> PoseCache::held_locked(const std::string& key,
                                                            const std::shared_ptr<const TriangleModel>& model) {
  const auto found_at = index_.find(key);
  if (found_at == index_.end()) return nullptr;
  const auto it = found_at->second;
  std::shared_ptr<const TriangleModel> found = it->kept ? it->kept : it->drawn.lock();
  if (!found || it->source.lock() != model) {
    erase(it);  // its pose is gone, or its model is another at the same address
    return nullptr;
  }
  it->kept = found;
  entries_.splice(entries_.begin(), entries_, it);
  return found;
}

void PoseCache::erase(std::list<Entry>::iterator it) {
  index_.erase(it->key);
  entries_.erase(it);
}

std::uint64_t PoseCache::live_bytes_locked() {
  std::uint64_t live = making_;
  for (auto it = entries_.begin(); it != entries_.end();) {
    if (!it->kept && it->drawn.expired()) {
      const auto dead = it++;
      erase(dead);
      continue;
    }
    live += it->bytes;
    ++it;
  }
  return live;
}

std::uint64_t PoseCache::bytes() {
  std::lock_guard<std::mutex> lock(mutex_);
  return live_bytes_locked();
}

void PoseCache::forget(const std::shared_ptr<const TriangleModel>& pose) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (Entry& e : entries_)
    if (e.kept == pose) e.kept.reset();
}

std::shared_ptr<const TriangleModel> PoseCache::posed(const std::shared_ptr<const TriangleModel>& model,
                                                      std::size_t animation, double t,
                                                      const std::function<bool()>& stop) {
  const ModelRig& rig = *model->rig;
  const std::string key = pose_key(model, animation, t);
  const std::uint64_t estimate = pose_bytes(*model);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (auto found = held_locked(key, model)) return found;
    if (estimate > max_bytes_)
      throw PoseRefused(422, "posed, the model would hold about " + mib(estimate) + ", more than the " + mib(max_bytes_) +
                                 " this server gives poses");
    // Room: drop reused poses, least recently used first (those still drawn
    // stay counted until their renders end), one scan and one pass.
    std::uint64_t live = live_bytes_locked();
    for (auto it = entries_.end(); it != entries_.begin() && (live + estimate > max_bytes_ || entries_.size() >= kMaxEntries);) {
      --it;
      if (!it->kept) continue;
      it->kept.reset();
      if (it->drawn.expired()) {
        live -= it->bytes;
        const auto dropped = it++;
        erase(dropped);
      }
    }
    if (live + estimate > max_bytes_ || entries_.size() >= kMaxEntries)
      throw PoseRefused(503, "poses of animated models fill this server's " + mib(max_bytes_) + " (or its " +
                                 std::to_string(kMaxEntries) + " poses) now, other renders drawing them; retry");
    making_ += estimate;
  }
  // The reservation goes back however the pose ends.
  struct Made {
    PoseCache& cache;
    std::uint64_t bytes;
    ~Made() {
      std::lock_guard<std::mutex> lock(cache.mutex_);
      cache.making_ -= bytes;
    }
  } reserved{*this, estimate};
  std::shared_ptr<TriangleModel> made;
  try {
    made = std::make_shared<TriangleModel>(pose_model(rig, animation, t, stop));
  } catch (const std::domain_error& e) {
    throw PoseRefused(422, "its pose at " + time_text(t) + " s: " + e.what());
  } catch (const PoseStopped&) {
    throw PoseRefused(499, "stopped: the client has gone");
  } catch (const std::bad_alloc&) {
    throw PoseRefused(503, "the server is short of memory for the pose now; retry");
  }
  made->skipped_primitives = model->skipped_primitives;
  std::lock_guard<std::mutex> lock(mutex_);
  // Made meanwhile by another request too: that one is shared (its entry
  // stays, so the pose it draws stays counted); this copy goes.
  if (auto found = held_locked(key, model)) return found;
  // The pose, and its record here (the entry, its key, the index's node).
  const std::uint64_t bytes = made->bytes() + sizeof(Entry) + 2 * key.capacity() + 64;
  entries_.push_front(Entry{key, model, made, made, bytes});
  index_[key] = entries_.begin();
  return made;
}

void PoseCache::pose_scene(Scene& scene, double time, const std::function<bool()>& stop) {
  const auto animated = [](const SceneObject& o) {
    return o.type == SceneObject::Type::Mesh && o.animation && o.model && o.model->rig;
  };
  const auto time_of = [&](const SceneObject& o) {
    const RigAnimation& animation = o.model->rig->animations.at(o.animation->index);
    return animation_time(animation.duration_s, time, o.animation->speed, o.animation->loop);
  };
  // The distinct poses asked for, together: what could never fit is
  // refused before any is made (a red-team pass: 8 poses of a 4M-triangle
  // model took 6 s of CPU, then a 503 asking to retry).
  std::set<std::string> keys;
  std::uint64_t together = 0;
  std::size_t last = 0;
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const SceneObject& o = scene.objects[i];
    if (!animated(o)) continue;
    if (keys.insert(pose_key(o.model, o.animation->index, time_of(o))).second) together += pose_bytes(*o.model);
    last = i;
  }
  if (together > max_bytes_)
    throw PoseRefused(422,
                      "the scene's " + std::to_string(keys.size()) + " poses of animated models would hold about " +
                          mib(together) + " together, more than the " + mib(max_bytes_) +
                          " this server gives poses: fewer distinct animations or times",
                      "scene.objects[" + std::to_string(last) + "].animation");
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    SceneObject& o = scene.objects[i];
    if (!animated(o)) continue;
    const double t = time_of(o);
    try {
      o.model = posed(o.model, o.animation->index, t, stop);
    } catch (const PoseRefused& e) {
      throw PoseRefused(e.status, e.what(), "scene.objects[" + std::to_string(i) + "].animation");
    }
    o.pose = "animation " + std::to_string(o.animation->index) + " at " + time_text(t) + " s";
    // The posed model, placed, must stay where float precision holds, as
    // the parser asks of its rest pose.
    const Aabb bounds = mesh_bounds(o);
    const double reach = bounds.reach();
    if (!bounds.empty() && reach > kMaxPosedCoordinate) {
      forget(o.model);
      throw PoseRefused(422,
                        "posed at " + time_text(t) + " s and placed, the model reaches coordinate " + time_text(reach) +
                            ", beyond " + time_text(kMaxPosedCoordinate),
                        "scene.objects[" + std::to_string(i) + "].animation");
    }
  }
}

}  // namespace umbra
