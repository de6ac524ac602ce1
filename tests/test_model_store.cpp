// The model store: ids, names, the byte budget (uploads dropped least
// recently used first, folder models pinned), and loading a --models folder.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <ctime>

#include "gltf_builder.hpp"
#include "assets/gltf_loader.hpp"
#include "assets/model_archive.hpp"
#include "assets/model_store.hpp"

namespace umbra {
namespace {

namespace fs = std::filesystem;

TEST(ModelStore, IdsAreSha256OfTheBody) {
  // FIPS 180-2, appendix B.
  EXPECT_EQ(model_id_for("abc"), "sha256:ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(model_id_for(""), "sha256:e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(model_id_for("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "sha256:248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  EXPECT_EQ(model_id_for(std::string(1000000, 'a')),
            "sha256:cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

// A model of `triangles` separate triangles.
std::shared_ptr<TriangleModel> model_of(std::size_t triangles) {
  auto model = std::make_shared<TriangleModel>();
  model->parts.emplace_back();
  for (std::size_t t = 0; t < triangles; ++t) {
    const float x = float(t);
    for (const glm::vec3& p : {glm::vec3(x, 0, 0), glm::vec3(x + 1, 0, 0), glm::vec3(x, 1, 0)}) {
      model->parts[0].indices.push_back(std::uint32_t(model->parts[0].positions.size()));
      model->parts[0].positions.push_back(p);
      model->parts[0].normals.push_back({0, 0, 1});
    }
  }
  finish_model(*model);
  return model;
}

TEST(ModelStore, AddFindAndAddAgain) {
  ModelStore store(1 << 20);
  const auto first = store.add("sha256:a", "", model_of(2), false);
  ASSERT_EQ(first.outcome, ModelStore::Outcome::Added);
  const auto again = store.add("sha256:a", "", model_of(2), false);
  EXPECT_EQ(again.outcome, ModelStore::Outcome::AlreadyHeld);
  EXPECT_EQ(again.held, first.held);
  EXPECT_EQ(store.find("sha256:a"), first.held);
  EXPECT_EQ(store.find("sha256:b"), nullptr);
  EXPECT_EQ(store.count(), 1u);
  EXPECT_EQ(store.bytes(), first.held->bytes);
}

TEST(ModelStore, UploadsLeaveLeastRecentlyUsedFirstAndPinnedOnesStay) {
  const std::uint64_t each = model_of(100)->bytes();
  ModelStore store(3 * each + each / 2);  // room for three
  ASSERT_EQ(store.add("sha256:pinned", "teapot", model_of(100), true).outcome, ModelStore::Outcome::Added);
  store.add("sha256:1", "", model_of(100), false);
  store.add("sha256:2", "", model_of(100), false);
  ASSERT_NE(store.find("sha256:1"), nullptr);  // 1 is now more recent than 2
  store.add("sha256:3", "", model_of(100), false);
  EXPECT_EQ(store.find("sha256:2"), nullptr);
  EXPECT_NE(store.find("sha256:1"), nullptr);
  EXPECT_NE(store.find("sha256:3"), nullptr);
  EXPECT_NE(store.find("teapot"), nullptr);
  EXPECT_NE(store.find("sha256:pinned"), nullptr);
  EXPECT_EQ(store.count(), 3u);
  EXPECT_LE(store.bytes(), store.max_bytes());
  const auto listed = store.list();
  ASSERT_EQ(listed.size(), 3u);
  EXPECT_EQ(listed[0]->name, "teapot");
  EXPECT_TRUE(listed[0]->pinned);
}

TEST(ModelStore, AModelLargerThanTheRoomLeftIsRefusedAndDropsNothing) {
  const std::uint64_t small = model_of(10)->bytes();
  ModelStore store(small * 3);
  store.add("sha256:pinned", "floor", model_of(10), true);
  store.add("sha256:1", "", model_of(10), false);
  EXPECT_EQ(store.add("sha256:big", "", model_of(1000), false).outcome, ModelStore::Outcome::TooLarge);
  EXPECT_NE(store.find("sha256:1"), nullptr);
  EXPECT_EQ(store.add("sha256:other", "floor", model_of(10), true).outcome, ModelStore::Outcome::NameTaken);
}

TEST(ModelStore, CountIsBoundedToo) {
  ModelStore store(1 << 30, 2);
  store.add("sha256:1", "", model_of(1), false);
  store.add("sha256:2", "", model_of(1), false);
  store.add("sha256:3", "", model_of(1), false);
  EXPECT_EQ(store.count(), 2u);
  EXPECT_EQ(store.find("sha256:1"), nullptr);
}

TEST(ModelStore, ConcurrentUploadsAndLookupsStayWithinBudget) {
  const std::uint64_t each = model_of(20)->bytes();
  ModelStore store(each * 5);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&store, t] {
      for (int i = 0; i < 200; ++i) {
        const std::string id = "sha256:" + std::to_string(t) + "-" + std::to_string(i % 17);
        store.add(id, "", model_of(20), false);
        store.find(id);
        store.list();
      }
    });
  for (auto& thread : threads) thread.join();
  EXPECT_LE(store.bytes(), store.max_bytes());
  EXPECT_LE(store.count(), 5u);
}

// --- Owners: one owner's uploads never evict another's models -------------

// A store with room for `models` models of model_of(100), and a share of
// `share` of them per owner.
ModelStore::Limits room_for(std::size_t models, std::size_t share) {
  const std::uint64_t each = model_of(100)->bytes();
  ModelStore::Limits limits;
  limits.max_bytes = models * each + each / 2;
  limits.share_bytes = share * each + each / 2;
  return limits;
}

// Adds a model of model_of(100) as `owner`'s upload, as the server does:
// room reserved for it first, then the model held in it.
ModelStore::Outcome upload(ModelStore& store, const std::string& owner, const std::string& id) {
  auto model = model_of(100);
  ModelStore::RoomResult room = store.reserve(owner, model->bytes());
  switch (room.outcome) {
    case ModelStore::Room::Made: return store.add_upload(id, std::move(model), room.reservation).outcome;
    case ModelStore::Room::NoRoomNow: return ModelStore::Outcome::NoRoom;
    default: return ModelStore::Outcome::TooLarge;
  }
}

TEST(ModelStore, AnOwnersUploadsEvictOnlyItsOwnModelsWithinOthersShares) {
  ModelStore store(room_for(4, 2));
  ASSERT_EQ(upload(store, "alice", "sha256:a1"), ModelStore::Outcome::Added);
  ASSERT_EQ(upload(store, "alice", "sha256:a2"), ModelStore::Outcome::Added);
  // Bob uploads many: each new one drops his own least recently used.
  for (int i = 0; i < 10; ++i)
    ASSERT_EQ(upload(store, "bob", "sha256:b" + std::to_string(i)), ModelStore::Outcome::Added) << i;
  EXPECT_NE(store.find("sha256:a1"), nullptr);
  EXPECT_NE(store.find("sha256:a2"), nullptr);
  EXPECT_NE(store.find("sha256:b9"), nullptr);
  EXPECT_NE(store.find("sha256:b8"), nullptr);
  EXPECT_EQ(store.find("sha256:b7"), nullptr);
  EXPECT_LE(store.live_bytes(), store.max_bytes());
  EXPECT_EQ(store.owner_bytes("alice"), 2 * model_of(100)->bytes());
}

TEST(ModelStore, RoomBorrowedPastAShareIsGivenBackToOtherOwners) {
  ModelStore store(room_for(4, 2));
  for (int i = 0; i < 4; ++i) ASSERT_EQ(upload(store, "alice", "sha256:a" + std::to_string(i)), ModelStore::Outcome::Added);
  EXPECT_EQ(store.count(), 4u);  // the whole budget, twice her share: free room borrowed
  ASSERT_EQ(upload(store, "bob", "sha256:b0"), ModelStore::Outcome::Added);
  ASSERT_EQ(upload(store, "bob", "sha256:b1"), ModelStore::Outcome::Added);
  // Her least recently used went, down to her share, and no further.
  EXPECT_EQ(store.find("sha256:a0"), nullptr);
  EXPECT_EQ(store.find("sha256:a1"), nullptr);
  EXPECT_NE(store.find("sha256:a2"), nullptr);
  EXPECT_NE(store.find("sha256:a3"), nullptr);
  EXPECT_EQ(upload(store, "carol", "sha256:c0"), ModelStore::Outcome::NoRoom);
  EXPECT_NE(store.find("sha256:a2"), nullptr);
  EXPECT_NE(store.find("sha256:b0"), nullptr);
}

TEST(ModelStore, AModelOverTheShareIsRefusedAndIdleModelsGoToAnyone) {
  ModelStore store(room_for(4, 2));
  const std::uint64_t each = model_of(100)->bytes();
  EXPECT_EQ(store.reserve("alice", 3 * each).outcome, ModelStore::Room::OverShare);
  EXPECT_EQ(store.reserve("alice", 5 * each).outcome, ModelStore::Room::OverShare);
  ModelStore whole(room_for(4, 4));
  EXPECT_EQ(whole.reserve("alice", 5 * each).outcome, ModelStore::Room::OverBudget);

  auto now = ModelStore::Clock::now();
  store.set_clock([&] { return now; });
  ASSERT_EQ(upload(store, "alice", "sha256:a0"), ModelStore::Outcome::Added);
  ASSERT_EQ(upload(store, "alice", "sha256:a1"), ModelStore::Outcome::Added);
  ASSERT_EQ(upload(store, "bob", "sha256:b0"), ModelStore::Outcome::Added);
  ASSERT_EQ(upload(store, "bob", "sha256:b1"), ModelStore::Outcome::Added);
  EXPECT_EQ(upload(store, "carol", "sha256:c0"), ModelStore::Outcome::NoRoom);
  now += ModelStore::kDefaultIdleDrop / 2;
  ASSERT_NE(store.find("sha256:b0"), nullptr);  // used: idle from now on
  now += ModelStore::kDefaultIdleDrop / 2 + std::chrono::seconds(1);
  ASSERT_EQ(upload(store, "carol", "sha256:c0"), ModelStore::Outcome::Added);
  EXPECT_EQ(store.find("sha256:a0"), nullptr);  // idle an hour: anyone's to drop
  EXPECT_NE(store.find("sha256:b0"), nullptr);
}

TEST(ModelStore, ReservationsAndModelsBeingDrawnCountAgainstTheBudget) {
  ModelStore store(room_for(3, 3));
  const std::uint64_t each = model_of(100)->bytes();
  ASSERT_EQ(upload(store, "", "sha256:1"), ModelStore::Outcome::Added);
  // A render draws 1: it is not dropped to make room, 2 is.
  const std::shared_ptr<const TriangleModel> drawn = drawn_model(store.find("sha256:1"));
  ASSERT_EQ(upload(store, "", "sha256:2"), ModelStore::Outcome::Added);
  ASSERT_EQ(upload(store, "", "sha256:3"), ModelStore::Outcome::Added);
  ASSERT_EQ(upload(store, "", "sha256:4"), ModelStore::Outcome::Added);
  EXPECT_NE(store.find("sha256:1"), nullptr);
  EXPECT_EQ(store.find("sha256:2"), nullptr);
  // A reservation holds its room until it is used or let go.
  {
    ModelStore::RoomResult room = store.reserve("", 2 * each);
    ASSERT_EQ(room.outcome, ModelStore::Room::Made);
    EXPECT_LE(store.live_bytes(), store.max_bytes());
    EXPECT_EQ(store.count(), 1u);  // 3 and 4 dropped for it; 1 is drawn
    EXPECT_EQ(store.reserve("", each).outcome, ModelStore::Room::NoRoomNow);
  }
  EXPECT_EQ(store.live_bytes(), each);
  EXPECT_EQ(store.reserve("", 2 * each).outcome, ModelStore::Room::Made);
  // A pinned model dropping 1 while it is drawn: still counted until the render lets it go.
  ModelStore pinned_later(room_for(2, 2));
  ASSERT_EQ(upload(pinned_later, "", "sha256:x"), ModelStore::Outcome::Added);
  const auto still_drawn = drawn_model(pinned_later.find("sha256:x"));
  ASSERT_EQ(pinned_later.add("sha256:p", "floor", model_of(200), true).outcome, ModelStore::Outcome::Added);
  EXPECT_EQ(pinned_later.find("sha256:x"), nullptr);
  EXPECT_EQ(pinned_later.live_bytes(), pinned_later.bytes() + each);
  EXPECT_EQ(pinned_later.reserve("", each / 4).outcome, ModelStore::Room::NoRoomNow);
}

TEST(ModelStore, AReservationTooSmallForTheModelGrowsOrRefuses) {
  ModelStore store(room_for(2, 2));
  const std::uint64_t each = model_of(100)->bytes();
  ModelStore::RoomResult room = store.reserve("", each / 2);
  ASSERT_EQ(room.outcome, ModelStore::Room::Made);
  EXPECT_EQ(store.add_upload("sha256:1", model_of(100), room.reservation).outcome, ModelStore::Outcome::Added);
  EXPECT_EQ(room.reservation.bytes(), 0u);
  ModelStore::RoomResult small = store.reserve("", 1);
  ASSERT_EQ(small.outcome, ModelStore::Room::Made);
  EXPECT_EQ(store.add_upload("sha256:big", model_of(1000), small.reservation).outcome, ModelStore::Outcome::TooLarge);
  EXPECT_NE(store.find("sha256:1"), nullptr);
}

TEST(ModelStore, AFolderLoadsByNameAndRefusesWhatLeavesIt) {
  const fs::path root = fs::temp_directory_path() / ("umbra-models-" + std::to_string(::getpid()));
  fs::create_directories(root / "models");
  test::GltfBuilder b;
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  test::unit_cube(positions, indices);
  b.scene({b.node({{"mesh", b.mesh(b.vec3s(positions), b.indices_u32(indices))}})});
  std::ofstream(root / "models" / "cube.bin", std::ios::binary) << b.bin;
  std::ofstream(root / "models" / "crate.gltf") << b.gltf_external("cube.bin");
  std::ofstream(root / "models" / "box.GLB", std::ios::binary) << b.glb();
  std::ofstream(root / "outside.bin", std::ios::binary) << b.bin;
  std::ofstream(root / "models" / "escape.gltf") << b.gltf_external("../outside.bin");
  std::ofstream(root / "models" / "broken.glb") << "glTF nope";
  std::ofstream(root / "models" / "notes.txt") << "not a model";

  ModelStore store(1 << 30);
  FolderLoad result;
  std::string error;
  ASSERT_TRUE(load_model_folder((root / "models").string(), store, 64 << 20, result, error)) << error;
  ASSERT_EQ(result.loaded.size(), 2u);
  EXPECT_EQ(result.loaded[0]->name, "box");
  EXPECT_EQ(result.loaded[1]->name, "crate");
  EXPECT_EQ(result.loaded[0]->id, model_id_for(b.glb()));
  EXPECT_EQ(store.find("crate")->model->triangle_count(), 12u);
  ASSERT_EQ(result.refused.size(), 2u);
  EXPECT_NE(result.refused[0].find("broken.glb: "), std::string::npos) << result.refused[0];
  EXPECT_NE(result.refused[1].find("escape.gltf: "), std::string::npos) << result.refused[1];
  EXPECT_NE(result.refused[1].find("outside the models folder"), std::string::npos) << result.refused[1];

  FolderLoad none;
  EXPECT_FALSE(load_model_folder((root / "absent").string(), store, 64 << 20, none, error));
  fs::remove_all(root);
}

}  // namespace
}  // namespace umbra

// --- The shared folder (--model-store) -------------------------------------

namespace umbra {
namespace {

struct TemporaryFolder {
  std::filesystem::path path;
  TemporaryFolder() {
    path = std::filesystem::temp_directory_path() /
           ("umbra-archive-" + std::to_string(getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~TemporaryFolder() { std::filesystem::remove_all(path); }
};

TEST(ModelArchive, KeepsABodyUnderItsIdAndGivesItBack) {
  TemporaryFolder folder;
  ModelArchive archive(folder.path.string());
  const std::string body = "glTF and then some bytes";
  const std::string id = model_id_for(body);
  std::string why;
  ASSERT_TRUE(archive.save(id, LoadOptions::Format::Binary, body, why)) << why;
  // Named by the id's hex, nothing else left in the folder (no temporary).
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(folder.path)) names.push_back(entry.path().filename());
  ASSERT_EQ(names.size(), 1u);
  EXPECT_EQ(names[0], id.substr(7) + ".glb");
  const auto stored = archive.load(id, 1 << 20, why);
  ASSERT_TRUE(stored) << why;
  EXPECT_EQ(stored->body, body);
  EXPECT_EQ(stored->format, LoadOptions::Format::Binary);
  // Saving again is a no-op; a .gltf is kept as such.
  EXPECT_TRUE(archive.save(id, LoadOptions::Format::Binary, body, why));
  const std::string json_body = R"({"asset": {"version": "2.0"}})";
  ASSERT_TRUE(archive.save(model_id_for(json_body), LoadOptions::Format::Json, json_body, why));
  EXPECT_EQ(archive.load(model_id_for(json_body), 1 << 20, why)->format, LoadOptions::Format::Json);
}

TEST(ModelArchive, TakesNoFileThatDoesNotHashToItsNameOrIsTooLarge) {
  TemporaryFolder folder;
  ModelArchive archive(folder.path.string());
  const std::string body = "the model's bytes";
  const std::string id = model_id_for(body);
  std::string why;
  ASSERT_TRUE(archive.save(id, LoadOptions::Format::Binary, body, why));
  EXPECT_FALSE(archive.load(id, 4, why)) << "larger than the limit";
  EXPECT_NE(why.find("larger than 4 bytes"), std::string::npos) << why;
  // Cut short (or changed) on the shared disk: refused, and said why.
  std::ofstream(folder.path / (id.substr(7) + ".glb"), std::ios::binary | std::ios::trunc) << "the model";
  why.clear();
  EXPECT_FALSE(archive.load(id, 1 << 20, why));
  EXPECT_NE(why.find("does not hash to its name"), std::string::npos) << why;
  // Not there: nullopt and no why.
  why.clear();
  EXPECT_FALSE(archive.load(model_id_for("other"), 1 << 20, why));
  EXPECT_TRUE(why.empty()) << why;
}

TEST(ModelArchive, NeverFormsAPathFromANameOrABadId) {
  TemporaryFolder folder;
  ModelArchive archive(folder.path.string());
  std::ofstream(folder.path / "teapot.glb") << "glTF";
  std::string why;
  for (const std::string& key : std::vector<std::string>{"teapot", "../teapot", "sha256:../../etc/passwd",
                                                        "sha256:" + std::string(64, 'A'),
                                                        "sha256:" + std::string(63, 'a')}) {
    EXPECT_FALSE(is_model_id(key)) << key;
    EXPECT_FALSE(archive.load(key, 1 << 20, why)) << key;
    EXPECT_FALSE(archive.save(key, LoadOptions::Format::Binary, "x", why)) << key;
  }
  EXPECT_TRUE(is_model_id(model_id_for("x")));
}

TEST(ModelArchive, AFolderItCannotWriteToIsSaidSo) {
  ModelArchive archive("/nonexistent-umbra-folder");
  std::string why;
  const ModelArchive::Saved saved = archive.save(model_id_for("x"), LoadOptions::Format::Binary, "x", why);
  EXPECT_FALSE(saved);
  // The client learns the id and the error; the server's path only its log.
  EXPECT_EQ(why.find("/nonexistent-umbra-folder"), std::string::npos) << why;
  EXPECT_NE(why.find(model_id_for("x").substr(0, 19)), std::string::npos) << why;
  EXPECT_NE(why.find("No such file"), std::string::npos) << why;
  EXPECT_NE(saved.detail.find("/nonexistent-umbra-folder"), std::string::npos) << saved.detail;
}

// Sets a file's mtime `seconds_ago` into the past: as if last used then.
void age(const std::filesystem::path& file, int seconds_ago) {
  const timespec times[2] = {{std::time(nullptr) - seconds_ago, 0}, {std::time(nullptr) - seconds_ago, 0}};
  ASSERT_EQ(::utimensat(AT_FDCWD, file.c_str(), times, 0), 0) << file;
}

std::vector<std::string> files_in(const std::filesystem::path& folder) {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) names.push_back(entry.path().filename());
  std::sort(names.begin(), names.end());
  return names;
}

// What the folder's files take on disk (allocated blocks).
std::uint64_t bytes_in(const std::filesystem::path& folder) {
  std::uint64_t total = 0;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    struct stat info {};
    if (::stat(entry.path().c_str(), &info) == 0) total += std::uint64_t(info.st_blocks) * 512;
  }
  return total;
}

// What one model of `body_bytes` and its record take on disk, at most.
constexpr std::uint64_t kModelOnDisk = 2 * 4096;

TEST(ModelArchive, TheFolderIsBoundedAndLeastRecentlyUsedFilesGoFirst) {
  TemporaryFolder folder;
  const std::size_t body_bytes = 1000;
  ModelArchive archive(folder.path.string(), 3 * kModelOnDisk + 4096);  // three bodies and their records
  const ModelArchive::Record record{123456, 12, ""};
  std::vector<std::string> ids;
  std::string why;
  for (int i = 0; i < 3; ++i) {
    const std::string body(body_bytes, char('a' + i));
    ids.push_back(model_id_for(body));
    ASSERT_TRUE(archive.save(ids.back(), LoadOptions::Format::Binary, body, why, record)) << why;
    age(folder.path / (ids.back().substr(7) + ".glb"), 1000 - 100 * i);  // 0 the oldest
  }
  ASSERT_EQ(files_in(folder.path).size(), 6u);  // each model and its record
  // Model 0 is used (loaded by some server): 1 is now the least recently used.
  ASSERT_TRUE(archive.load(ids[0], 1 << 20, why)) << why;
  const std::string fourth(body_bytes, 'z');
  ASSERT_TRUE(archive.save(model_id_for(fourth), LoadOptions::Format::Binary, fourth, why, record)) << why;
  EXPECT_TRUE(archive.find(ids[0]));
  EXPECT_FALSE(archive.find(ids[1]));
  EXPECT_FALSE(std::filesystem::exists(folder.path / (ids[1].substr(7) + ".json")));  // its record went with it
  EXPECT_TRUE(archive.find(ids[2]));
  EXPECT_LE(bytes_in(folder.path), archive.max_bytes());
  EXPECT_EQ(archive.evicted(), 1u);
  // A deleted model is simply unknown; saved again, it is back.
  why.clear();
  EXPECT_FALSE(archive.load(ids[1], 1 << 20, why));
  EXPECT_TRUE(why.empty()) << why;
  ASSERT_TRUE(archive.save(ids[1], LoadOptions::Format::Binary, std::string(body_bytes, 'b'), why, record));
  EXPECT_TRUE(archive.load(ids[1], 1 << 20, why));
  EXPECT_LE(bytes_in(folder.path), archive.max_bytes());
  // Larger than the whole folder may hold: refused, nothing written.
  // Never: TooLarge (422), not a refusal to retry.
  const std::string huge(4 * kModelOnDisk, 'h');
  EXPECT_EQ(archive.save(model_id_for(huge), LoadOptions::Format::Binary, huge, why).status,
            ModelArchive::Status::TooLarge);
  EXPECT_NE(why.find("--model-store-max-gib"), std::string::npos) << why;
  EXPECT_FALSE(archive.find(model_id_for(huge)));
}

TEST(ModelArchive, RecordsSayWhatAModelHoldsWithoutReadingIt) {
  TemporaryFolder folder;
  ModelArchive archive(folder.path.string());
  std::string why;
  const std::string body = "glTF a model";
  ASSERT_TRUE(archive.save(model_id_for(body), LoadOptions::Format::Binary, body, why, ModelArchive::Record{5000, 7, ""}));
  std::optional<ModelArchive::Found> found = archive.find(model_id_for(body));
  ASSERT_TRUE(found);
  EXPECT_EQ(found->file_bytes, body.size());
  ASSERT_TRUE(found->record);
  EXPECT_EQ(found->record->bytes_bound, 5000u);
  EXPECT_EQ(found->record->triangles, 7u);
  // Without a record (an older server wrote it, or it was cut short): none.
  const std::string other = "glTF another";
  ASSERT_TRUE(archive.save(model_id_for(other), LoadOptions::Format::Json, other, why));
  EXPECT_FALSE(archive.find(model_id_for(other))->record);
  std::ofstream(folder.path / (model_id_for(other).substr(7) + ".json")) << "{\"bytes_bound\": 5";
  EXPECT_FALSE(archive.find(model_id_for(other))->record);
  archive.write_record(model_id_for(other), {900, 3, ""});
  EXPECT_EQ(archive.find(model_id_for(other))->record->bytes_bound, 900u);
  EXPECT_EQ(archive.find(model_id_for(other))->format, LoadOptions::Format::Json);
}

TEST(ModelArchive, AFullDiskEvictsThenSaysNoSpaceAndLeavesNothingBehind) {
  TemporaryFolder folder;
  ModelArchive archive(folder.path.string());
  std::string why;
  const std::string old_body(5000, 'o');
  ASSERT_TRUE(archive.save(model_id_for(old_body), LoadOptions::Format::Binary, old_body, why));
  // The disk takes no more than what is free: here, nothing until the old model goes.
  archive.write_for_test = [&](int fd, const void* data, std::size_t size) -> ssize_t {
    if (archive.find(model_id_for(old_body))) {
      errno = ENOSPC;
      return -1;
    }
    return ::write(fd, data, size);
  };
  const std::string body(3000, 'n');
  ASSERT_TRUE(archive.save(model_id_for(body), LoadOptions::Format::Binary, body, why)) << why;
  EXPECT_FALSE(archive.find(model_id_for(old_body)));
  EXPECT_TRUE(archive.load(model_id_for(body), 1 << 20, why)) << why;
  // Full whatever is deleted: NoSpace, and no file, no temporary left.
  archive.write_for_test = [](int, const void*, std::size_t) -> ssize_t {
    errno = ENOSPC;
    return -1;
  };
  const std::string refused(100, 'r');
  EXPECT_EQ(archive.save(model_id_for(refused), LoadOptions::Format::Binary, refused, why).status,
            ModelArchive::Status::NoSpace);
  EXPECT_NE(why.find("No space"), std::string::npos) << why;
  EXPECT_TRUE(files_in(folder.path).empty()) << files_in(folder.path).size();
}

TEST(ModelArchive, StrayTemporaryFilesOfACrashAreDeleted) {
  TemporaryFolder folder;
  ModelArchive archive(folder.path.string());
  std::ofstream(folder.path / ".upload-0123-crashed") << "half a model";
  std::ofstream(folder.path / ".upload-4567-writing") << "a write under way";
  std::ofstream(folder.path / "notes.txt") << "not the store's";
  age(folder.path / ".upload-0123-crashed", 2 * 3600);
  std::string why;
  ASSERT_TRUE(archive.save(model_id_for("x"), LoadOptions::Format::Binary, "x", why));
  EXPECT_FALSE(std::filesystem::exists(folder.path / ".upload-0123-crashed"));
  EXPECT_TRUE(std::filesystem::exists(folder.path / ".upload-4567-writing"));
  EXPECT_TRUE(std::filesystem::exists(folder.path / "notes.txt"));
}

// Finding 1 (round 2): a load's buffer is sized by the file, not by the
// limit: a 300-byte model under a 4 TiB limit takes 301 bytes, not 4 TiB.
TEST(ModelArchive, ALoadTakesABufferTheSizeOfTheFileNotOfTheLimit) {
  TemporaryFolder folder;
  ModelArchive archive(folder.path.string());
  const std::string body(300, 'm');
  std::string why;
  ASSERT_TRUE(archive.save(model_id_for(body), LoadOptions::Format::Binary, body, why));
  const auto stored = archive.load(model_id_for(body), std::size_t(1) << 42, why);
  ASSERT_TRUE(stored) << why;
  EXPECT_EQ(stored->body, body);
  EXPECT_LE(stored->body.capacity(), std::size_t(1) << 20);
}

std::string owned_body(int n) { return "model " + std::to_string(n) + std::string(1000, 'x'); }

// Finding 2 (round 2): the folder's owners, as in ModelStore: an upload
// deletes its owner's files, others' beyond their share, or idle ones;
// otherwise NoRoomNow, deleting nothing.
TEST(ModelArchive, OneOwnersUploadsNeverDeleteAnothersFilesWithinItsShare) {
  TemporaryFolder folder;
  ModelArchive::Limits limits;
  limits.max_bytes = 4 * kModelOnDisk;
  limits.share_bytes = 2 * kModelOnDisk;
  ModelArchive archive(folder.path.string(), limits);
  std::string why;
  const auto save = [&](int n, const std::string& owner) {
    return archive.save(model_id_for(owned_body(n)), LoadOptions::Format::Binary, owned_body(n), why,
                        ModelArchive::Record{1, 1, owner});
  };
  const auto stored = [&](int n) { return archive.find(model_id_for(owned_body(n))).has_value(); };
  ASSERT_TRUE(save(0, "alice")) << why;
  age(folder.path / (model_id_for(owned_body(0)).substr(7) + ".glb"), 500);  // the least recently used
  EXPECT_EQ(archive.find(model_id_for(owned_body(0)))->owner, "alice");
  // Bob uploads 18: each one past the bound deletes his own oldest.
  for (int n = 1; n <= 18; ++n) {
    ASSERT_TRUE(save(n, "bob")) << n << ": " << why;
    age(folder.path / (model_id_for(owned_body(n)).substr(7) + ".glb"), 400 - n);
    EXPECT_LE(bytes_in(folder.path), limits.max_bytes) << n;
  }
  EXPECT_TRUE(stored(0)) << "alice's model was deleted for bob's uploads";
  EXPECT_TRUE(stored(18));
  EXPECT_FALSE(stored(1));
  // Alice's next upload deletes her own least recently used file first.
  ASSERT_TRUE(save(20, "alice")) << why;
  EXPECT_FALSE(stored(0));
  EXPECT_TRUE(stored(16));
  // Carol may take what bob holds beyond his share (3 > 2): his oldest.
  ASSERT_TRUE(save(30, "carol")) << why;
  EXPECT_FALSE(stored(16));
  EXPECT_TRUE(stored(20));
  // Now everyone is within their share: dave may delete nothing, and does not.
  const std::vector<std::string> before = files_in(folder.path);
  EXPECT_EQ(save(40, "dave").status, ModelArchive::Status::NoRoomNow);
  EXPECT_NE(why.find("retry later"), std::string::npos) << why;
  EXPECT_EQ(files_in(folder.path), before);
  // A file unused past idle_delete goes for anyone.
  age(folder.path / (model_id_for(owned_body(20)).substr(7) + ".glb"), 500);
  ModelArchive::Limits idle = limits;
  idle.idle_delete = std::chrono::seconds(450);
  ModelArchive patient(folder.path.string(), idle);
  ASSERT_TRUE(patient.save(model_id_for(owned_body(40)), LoadOptions::Format::Binary, owned_body(40), why,
                           ModelArchive::Record{1, 1, "dave"}))
      << why;
  EXPECT_FALSE(stored(20));  // alice's, unused for 500 s
  EXPECT_TRUE(stored(30));
  EXPECT_TRUE(stored(17));
  // Files of an older server (records without an owner, or none) are the anonymous owner's.
  std::ofstream(folder.path / (model_id_for(owned_body(30)).substr(7) + ".json"), std::ios::trunc)
      << R"({"bytes_bound": 1, "triangles": 1})";
  EXPECT_EQ(archive.find(model_id_for(owned_body(30)))->owner, "");
}

// Finding 3 (round 2): the bound counts blocks on disk (a 100-byte file
// takes 4 KiB), and the number of model files is bounded too.
TEST(ModelArchive, TheBoundCountsAllocatedBlocksAndFiles) {
  TemporaryFolder folder;
  ModelArchive archive(folder.path.string(), 10 * kModelOnDisk);
  std::string why;
  for (int n = 0; n < 30; ++n) {
    const std::string body = "small " + std::to_string(n);
    ASSERT_TRUE(archive.save(model_id_for(body), LoadOptions::Format::Binary, body, why, ModelArchive::Record{1, 1, ""}))
        << why;
  }
  EXPECT_LE(bytes_in(folder.path), archive.max_bytes());
  EXPECT_LE(files_in(folder.path).size(), 2u * 10);
  ModelArchive::Limits few;
  few.max_files = 3;
  TemporaryFolder other;
  ModelArchive counted(other.path.string(), few);
  for (int n = 0; n < 5; ++n) {
    const std::string body = "tiny " + std::to_string(n);
    ASSERT_TRUE(counted.save(model_id_for(body), LoadOptions::Format::Binary, body, why)) << why;
  }
  EXPECT_EQ(files_in(other.path).size(), 3u);
}

// Finding 4 (round 2): a record that claims more than an upload of its
// file could hold is not taken (its owner is).
TEST(ModelArchive, ARecordClaimingTheImpossibleIsNotTaken) {
  TemporaryFolder folder;
  ModelArchive archive(folder.path.string());
  const std::string body = "glTF small";
  std::string why;
  ASSERT_TRUE(archive.save(model_id_for(body), LoadOptions::Format::Binary, body, why,
                           ModelArchive::Record{~std::uint64_t(0), 1, "alice"}));
  const auto found = archive.find(model_id_for(body));
  ASSERT_TRUE(found);
  EXPECT_FALSE(found->record);
  EXPECT_EQ(found->owner, "alice");
  archive.write_record(model_id_for(body), {max_loaded_bytes(body.size()), 1, "alice"});
  EXPECT_TRUE(archive.find(model_id_for(body))->record);
}

}  // namespace
}  // namespace umbra
