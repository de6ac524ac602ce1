// Posed models: the mesh objects of a request that name an animation
// (`"animation"`, docs/api.md) are drawn as their model posed at the
// request's time (core/model_rig.hpp). A pose asked again (a panel playing
// a loop, a cluster answering the same frame) is shared, so the ray
// caster's BVH cache, keyed by model, finds it too.
//
// Bounded in bytes: poses held for reuse and poses still drawn by renders
// together stay within `max_bytes`. Reused poses are dropped least
// recently used first to make room; when renders hold the rest, a new pose
// is refused (503, retry) rather than grown past the bound. Thread-safe;
// posing runs outside the lock. Pure: no GL, no HTTP. Tested in
// tests/test_model_rig.cpp.
#pragma once

#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "core/model.hpp"
#include "core/request.hpp"

namespace umbra {

/// A pose the cache will not make: 422 (larger than the whole bound, or not
/// finite) or 503 (the room is held by renders now).
struct PoseRefused : std::runtime_error {
  PoseRefused(int status_, const std::string& message, std::string field_ = "")
      : std::runtime_error(message), status(status_), field(std::move(field_)) {}
  int status;
  std::string field;  ///< the request field it names ("scene.objects[2].animation"), if any
};

/// Where a posed, placed model must stay (the request's coordinate limit).
constexpr double kMaxPosedCoordinate = 1e6;

class PoseCache {
 public:
  static constexpr std::uint64_t kDefaultMaxBytes = std::uint64_t(512) << 20;
  explicit PoseCache(std::uint64_t max_bytes = kDefaultMaxBytes) : max_bytes_(max_bytes) {}

  /// `model` (which has a rig) posed by its animation `animation` at that
  /// animation's own time `t` seconds: shared with earlier askers of the
  /// same pose. Throws PoseRefused.
  /// `stop`, if given, is asked while the pose is made: true ends it
  /// (PoseRefused 499).
  std::shared_ptr<const TriangleModel> posed(const std::shared_ptr<const TriangleModel>& model, std::size_t animation,
                                             double t, const std::function<bool()>& stop = nullptr);

  /// Poses every mesh object of `scene` that names an animation at request
  /// time `time`: its `model` becomes the posed one and its `pose` names it.
  /// The distinct poses the scene asks for must fit the bound together
  /// (else 422 at once, before any is made: retrying would not help).
  /// Throws PoseRefused (its field names the object).
  void pose_scene(Scene& scene, double time, const std::function<bool()>& stop = nullptr);

  /// Bytes of poses held or still drawn, and poses being made.
  std::uint64_t bytes();

 private:
  struct Entry {
    std::string key;
    std::weak_ptr<const TriangleModel> source;  ///< the rest model it was posed from
    std::weak_ptr<const TriangleModel> drawn;   ///< alive while any render holds it
    std::shared_ptr<const TriangleModel> kept;  ///< held for reuse (dropped to make room)
    std::uint64_t bytes = 0;
  };
  std::uint64_t live_bytes_locked();
  /// No longer keeps `pose` for reuse (a pose its request refused).
  void forget(const std::shared_ptr<const TriangleModel>& pose);

  /// Entries held at most (kept or drawn): a client stepping `time` over a
  /// tiny model makes a pose each step; the bound keeps each call's scan
  /// short and the records' own memory (counted in their bytes) small.
  static constexpr std::size_t kMaxEntries = 4096;
  /// The pose held under `key` for `model`, kept for reuse and made the
  /// most recently used; null (a stale entry erased) if none.
  std::shared_ptr<const TriangleModel> held_locked(const std::string& key,
                                                   const std::shared_ptr<const TriangleModel>& model);
  /// Erases `it` from the list and the index.
  void erase(std::list<Entry>::iterator it);

  std::mutex mutex_;
  std::list<Entry> entries_;  ///< most recently used first
  std::unordered_map<std::string, std::list<Entry>::iterator> index_;  ///< by key
  std::uint64_t making_ = 0;  ///< bytes of poses being made now
  std::uint64_t max_bytes_;
};

}  // namespace umbra
