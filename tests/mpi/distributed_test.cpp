// DistributedDetector against a brute force over the whole scene, under mpirun with 1-4 ranks.
//
// Every rank builds the same scene from the same seed, takes the objects a partition gives it,
// and runs the distributed frame; rank 0 compares the gathered pairs with the reference backend's
// pairs over all objects, and every rank compares its objects' states. Assertions are EXPECTs:
// a rank that returned early would leave the others waiting in a collective.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "viscd/mpi.hpp"
#include "viscd/viscd.hpp"

namespace viscd::mpi {
inline void PrintTo(const GlobalPair& p, std::ostream* os) { *os << "(" << p.a << "," << p.b << ")"; }
}  // namespace viscd::mpi

namespace {

using namespace viscd;
using viscd::mpi::DistributedDetector;
using viscd::mpi::DistributedInput;
using viscd::mpi::DistributedResult;
using viscd::mpi::GlobalPair;

int world_rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}
int world_size() {
  int k = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &k);
  return k;
}

/// A whole scene: moving and static objects of one kind, their global ids and filters.
struct Scene {
  bool boxes = false;
  std::vector<Sphere> spheres, static_spheres;
  std::vector<Box> box, static_box;
  std::vector<std::uint64_t> ids, static_ids;
  std::vector<Filter> filters, static_filters;  // empty: none
  std::vector<int> owner, static_owner;         // the rank that holds each object
  [[nodiscard]] std::size_t size() const { return boxes ? box.size() : spheres.size(); }
  [[nodiscard]] std::size_t static_size() const { return boxes ? static_box.size() : static_spheres.size(); }
};

/// Global ids far from the indices and not in index order: 2^40 + a shuffled multiple of 7.
std::vector<std::uint64_t> shuffled_ids(std::size_t n, std::uint64_t first, std::mt19937_64& rng) {
  std::vector<std::uint64_t> ids(n);
  for (std::size_t i = 0; i < n; ++i) ids[i] = (std::uint64_t{1} << 40) + 7 * (first + i);
  std::shuffle(ids.begin(), ids.end(), rng);
  return ids;
}

Box cube(const Sphere& s) { return Box{{s.x - s.r, s.y - s.r, s.z - s.r}, {s.x + s.r, s.y + s.r, s.z + s.r}}; }

/// Slabs along x: an object goes to the rank whose slab holds its centre.
int slab_of(float x, float lo, float hi, int k) {
  const int r = static_cast<int>(std::floor((x - lo) / (hi - lo) * static_cast<float>(k)));
  return std::clamp(r, 0, k - 1);
}

enum class Layout { uniform, flat, boundaries, huge, by_index, blocks };

Scene make_scene(Layout layout, std::size_t n, std::size_t n_static, bool boxes, bool filters, std::uint64_t seed) {
  const int k = world_size();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0, 100), rad(0.5f, 3.0f), jitter(-2, 2);
  Scene s;
  s.boxes = boxes;
  auto shape = [&](std::size_t i) {
    Sphere sp{u(rng), u(rng), u(rng), rad(rng)};
    switch (layout) {
      case Layout::flat:
        sp.z = 0;
        break;
      case Layout::boundaries: {  // on the slab cuts, where every pair spans two ranks
        const int cut = static_cast<int>(i % static_cast<std::size_t>(std::max(k - 1, 1))) + 1;
        sp.x = 100.0f * static_cast<float>(cut) / static_cast<float>(k) + jitter(rng);
        break;
      }
      case Layout::huge:
        if (i == 0) sp = {50, 50, 50, 1000};  // spans every rank's region
        break;
      default:
        break;
    }
    return sp;
  };
  std::vector<Sphere> moving(n), fixed(n_static);
  for (std::size_t i = 0; i < n; ++i) moving[i] = shape(i);
  for (auto& f : fixed) f = {u(rng), u(rng), u(rng), rad(rng) * 2};
  auto all_ids = shuffled_ids(n + n_static, 0, rng);
  if (layout == Layout::blocks)  // ids counting up, each rank a block of them: the consecutive-id path
    for (std::size_t i = 0; i < all_ids.size(); ++i) all_ids[i] = 1000 + i;
  s.ids.assign(all_ids.begin(), all_ids.begin() + static_cast<std::ptrdiff_t>(n));
  s.static_ids.assign(all_ids.begin() + static_cast<std::ptrdiff_t>(n), all_ids.end());
  for (std::size_t i = 0; i < n; ++i)
    s.owner.push_back(layout == Layout::by_index ? static_cast<int>(i % static_cast<std::size_t>(k))
                      : layout == Layout::blocks ? static_cast<int>(i * static_cast<std::size_t>(k) / n)
                                                 : slab_of(moving[i].x, 0, 100, k));
  for (std::size_t i = 0; i < n_static; ++i) s.static_owner.push_back(slab_of(fixed[i].x, 0, 100, k));
  if (boxes) {
    for (const auto& m : moving) s.box.push_back(cube(m));
    for (const auto& f : fixed) s.static_box.push_back(cube(f));
  } else {
    s.spheres = moving;
    s.static_spheres = fixed;
  }
  if (filters) {
    std::uniform_int_distribution<std::uint32_t> bits(0, 3);
    s.filters.resize(n);
    for (auto& f : s.filters) f = {1u << bits(rng), 0xFFFFFFFFu ^ (1u << bits(rng))};
    s.static_filters.resize(n_static);
    for (auto& f : s.static_filters) f = {1u << bits(rng), 0xFFFFFFFFu ^ (1u << bits(rng))};
  }
  return s;
}

/// The oracle: the reference backend (brute force) over every object, in global ids.
struct Expected {
  std::vector<GlobalPair> pairs;
  std::vector<ObjectState> state;  // by scene index
};

Expected brute_force(const Scene& s) {
  auto det = make_reference_detector();
  if (s.boxes)
    EXPECT_TRUE(det->set_static_boxes(s.static_box, s.static_filters).ok());
  else
    EXPECT_TRUE(det->set_static_spheres(s.static_spheres, s.static_filters).ok());
  FrameInput in;
  in.spheres = s.spheres;
  in.boxes = s.box;
  in.filters = s.filters;
  FrameResult out;
  const Status st = det->detect(in, out);
  EXPECT_TRUE(st.ok()) << st.error();
  Expected e;
  for (const Pair& p : out.pairs) {
    const std::uint64_t a = s.ids[p.i], b = is_static_index(p.j) ? s.static_ids[static_slot(p.j)] : s.ids[p.j];
    e.pairs.push_back({std::min(a, b), std::max(a, b)});
  }
  std::sort(e.pairs.begin(), e.pairs.end());
  e.state = out.state;
  return e;
}

/// This rank's share of a scene.
struct Share {
  std::vector<Sphere> spheres, static_spheres;
  std::vector<Box> box, static_box;
  std::vector<std::uint64_t> ids, static_ids;
  std::vector<Filter> filters, static_filters;
  std::vector<std::size_t> index;  // scene index of each own moving object
  [[nodiscard]] DistributedInput input() const {
    DistributedInput in;
    in.spheres = spheres;
    in.boxes = box;
    in.ids = ids;
    in.filters = filters;
    return in;
  }
};

Share share_of(const Scene& s, int rank) {
  Share m;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s.owner[i] != rank) continue;
    m.index.push_back(i);
    m.ids.push_back(s.ids[i]);
    if (s.boxes)
      m.box.push_back(s.box[i]);
    else
      m.spheres.push_back(s.spheres[i]);
    if (!s.filters.empty()) m.filters.push_back(s.filters[i]);
  }
  for (std::size_t i = 0; i < s.static_size(); ++i) {
    if (s.static_owner[i] != rank) continue;
    m.static_ids.push_back(s.static_ids[i]);
    if (s.boxes)
      m.static_box.push_back(s.static_box[i]);
    else
      m.static_spheres.push_back(s.static_spheres[i]);
    if (!s.static_filters.empty()) m.static_filters.push_back(s.static_filters[i]);
  }
  return m;
}

/// One distributed frame of `s` checked against the brute force: pairs gathered on rank 0 and
/// every rank's states. Returns the rank's result for further checks.
DistributedResult check_frame(DistributedDetector& det, const Scene& s, const std::string& what) {
  const int rank = det.rank();
  const Share m = share_of(s, rank);
  Status st = s.boxes ? det.set_static_boxes(m.static_box, m.static_ids, m.static_filters)
                      : det.set_static_spheres(m.static_spheres, m.static_ids, m.static_filters);
  EXPECT_TRUE(st.ok()) << what << ": " << st.error();
  DistributedResult out;
  st = det.detect(m.input(), out);
  EXPECT_TRUE(st.ok()) << what << ": " << st.error();
  std::vector<GlobalPair> all;
  st = det.gather_pairs(out, all);
  EXPECT_TRUE(st.ok()) << what << ": " << st.error();
  const Expected e = brute_force(s);
  if (rank == 0) {
    EXPECT_EQ(all.size(), e.pairs.size()) << what;
    EXPECT_TRUE(all == e.pairs) << what << ": the gathered pairs differ from the brute force";
  } else {
    EXPECT_TRUE(all.empty()) << what << ": pairs gathered on a rank that is not root";
  }
  EXPECT_TRUE(std::is_sorted(out.pairs.begin(), out.pairs.end())) << what;
  EXPECT_EQ(out.state.size(), m.index.size()) << what;
  for (std::size_t k = 0; k < std::min(out.state.size(), m.index.size()); ++k)
    EXPECT_EQ(out.state[k], e.state[m.index[k]]) << what << ": object " << m.index[k];
  // Every pair is reported once over all ranks.
  std::uint64_t mine = out.pairs.size(), total = 0;
  MPI_Allreduce(&mine, &total, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(total, e.pairs.size()) << what;
  return out;
}

struct Case {
  const char* name;
  Layout layout;
  std::size_t n, n_static;
  bool boxes, filters;
};

TEST(DistributedDetector, EqualsOneProcess) {
  const Case cases[] = {
      {"uniform spheres", Layout::uniform, 1500, 0, false, false},
      {"uniform boxes", Layout::uniform, 1500, 0, true, false},
      {"flat", Layout::flat, 1200, 0, false, false},
      {"clustered on the rank boundaries", Layout::boundaries, 900, 0, false, false},
      {"clustered on the rank boundaries, boxes", Layout::boundaries, 900, 0, true, false},
      {"one huge object over every rank", Layout::huge, 800, 0, false, false},
      {"one huge box over every rank", Layout::huge, 800, 0, true, false},
      {"owners by index: every region overlaps", Layout::by_index, 700, 0, false, false},
      {"filters", Layout::uniform, 1500, 0, false, true},
      {"ids counting up, a block per rank", Layout::blocks, 1500, 0, false, false},
      {"ids counting up, boxes and static boxes", Layout::blocks, 1200, 200, true, true},
      {"static objects per rank", Layout::uniform, 1000, 300, false, false},
      {"static boxes with filters", Layout::uniform, 1000, 300, true, true},
      {"fewer objects than ranks", Layout::uniform, 2, 0, false, false},
      {"one object", Layout::uniform, 1, 0, false, false},
      {"no objects", Layout::uniform, 0, 0, false, false},
      {"no moving objects, static ones", Layout::uniform, 0, 50, true, false},
  };
  std::uint64_t seed = 1;
  for (const Case& c : cases) {
    DistributedDetector det(MPI_COMM_WORLD);
    check_frame(det, make_scene(c.layout, c.n, c.n_static, c.boxes, c.filters, seed++), c.name);
  }
}

TEST(DistributedDetector, TouchingAcrossTheCut) {
  // Two spheres touching exactly at a slab cut, owned by the ranks on either side; and boxes
  // sharing a face there.
  const int k = world_size();
  const float cut = k > 1 ? 100.0f / static_cast<float>(k) : 50;
  for (const bool boxes : {false, true}) {
    Scene s;
    s.boxes = boxes;
    const Sphere a{cut - 1, 5, 5, 1}, b{cut + 1, 5, 5, 1}, c{cut + 3.5f, 5, 5, 0.5f};
    for (const Sphere& sp : {a, b, c}) {
      if (boxes)
        s.box.push_back(cube(sp));
      else
        s.spheres.push_back(sp);
    }
    s.ids = {30, 20, 10};
    s.owner = {0, std::min(1, k - 1), std::min(1, k - 1)};
    DistributedDetector det(MPI_COMM_WORLD);
    const auto out = check_frame(det, s, boxes ? "touching boxes" : "touching spheres");
    (void)out;
  }
}

TEST(DistributedDetector, FramesWhereObjectsMoveBetweenRanks) {
  // Objects drift along x so that they change owners; some appear and some vanish; statics move
  // too; the ghosts' static set follows by id.
  const int k = world_size();
  Scene s = make_scene(Layout::uniform, 800, 120, false, true, 99);
  DistributedDetector det(MPI_COMM_WORLD);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> step(-4, 4);
  std::uint64_t next_id = 1;
  for (int frame = 0; frame < 8; ++frame) {
    for (auto& sp : s.spheres) sp.x = std::clamp(sp.x + step(rng), 0.0f, 100.0f);
    if (frame % 3 == 2) {  // one static object moves, and its filter changes
      s.static_spheres[frame].x += 10;
      s.static_filters[frame] = Filter{2, 0xFFFFFFFDu};
    }
    if (frame == 4) {  // a few vanish, a few new ones appear with new ids
      s.spheres.resize(s.spheres.size() - 50);
      s.ids.resize(s.spheres.size());
      s.filters.resize(s.spheres.size());
      for (int i = 0; i < 20; ++i) {
        s.spheres.push_back({step(rng) + 50, step(rng) + 50, step(rng) + 50, 2});
        s.ids.push_back(next_id++);
        s.filters.push_back(Filter{});
      }
    }
    s.owner.clear();
    for (const auto& sp : s.spheres) s.owner.push_back(slab_of(sp.x, 0, 100, k));
    s.static_owner.clear();
    for (const auto& sp : s.static_spheres) s.static_owner.push_back(slab_of(sp.x, 0, 100, k));
    check_frame(det, s, "frame " + std::to_string(frame));
  }
}

/// The status every rank gets from a frame where `bad_rank` alone gives `bad` input.
void expect_same_failure_everywhere(const Status& st, ErrorKind kind, const std::string& needle) {
  EXPECT_FALSE(st.ok());
  EXPECT_EQ(st.kind(), kind) << st.error();
  EXPECT_NE(st.error().find(needle), std::string::npos) << st.error();
  // The same message on every rank: compare lengths and a hash with rank 0's.
  std::uint64_t h = std::hash<std::string>{}(st.error()), h0 = h;
  MPI_Bcast(&h0, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
  EXPECT_EQ(h, h0) << "rank " << world_rank() << " got: " << st.error();
}

TEST(DistributedDetector, BadInputOnOneRankFailsEveryRank) {
  const int rank = world_rank(), k = world_size();
  const int bad = k - 1;
  Scene s = make_scene(Layout::uniform, 400, 0, false, false, 7);
  const Share m = share_of(s, rank);
  DistributedDetector det(MPI_COMM_WORLD);
  DistributedResult out;
  {  // a NaN on the last rank
    Share mine = m;
    if (rank == bad) mine.spheres.push_back({std::numeric_limits<float>::quiet_NaN(), 0, 0, 1}), mine.ids.push_back(1);
    const Status st = det.detect(mine.input(), out);
    expect_same_failure_everywhere(st, ErrorKind::invalid_input, "rank " + std::to_string(bad) + ": sphere");
  }
  {  // an id given twice: by rank 0 and by the last rank (or twice on rank 0 with one rank)
    Share mine = m;
    if (rank == bad) mine.spheres.push_back({1, 1, 1, 1}), mine.ids.push_back(s.ids[0]);
    const Status st = det.detect(mine.input(), out);
    expect_same_failure_everywhere(st, ErrorKind::invalid_input, "is given twice");
  }
  {  // one id too few
    Share mine = m;
    if (rank == bad) mine.ids.push_back(12345);
    const Status st = det.detect(mine.input(), out);
    expect_same_failure_everywhere(st, ErrorKind::invalid_input, "ids for");
  }
  if (k > 1) {  // boxes on one rank, spheres on the others
    Share mine = m;
    if (rank == bad) {
      mine.box.clear();
      for (const auto& sp : mine.spheres) mine.box.push_back(cube(sp));
      mine.spheres.clear();
    }
    const Status st = det.detect(mine.input(), out);
    expect_same_failure_everywhere(st, ErrorKind::invalid_input, "must be of one kind");
  }
  // After the failures the detector still works.
  check_frame(det, s, "after failures");
}

TEST(DistributedDetector, PairCapOnOneRank) {
  // 400 coincident spheres on the last rank and a cap that holds none of their pairs: every
  // rank fails with pair_cap.
  const int rank = world_rank(), k = world_size();
  Config config;
  config.pair_memory_cap = 1000;
  DistributedDetector det(MPI_COMM_WORLD, config);
  std::vector<Sphere> spheres;
  std::vector<std::uint64_t> ids;
  if (rank == k - 1)
    for (std::uint64_t i = 0; i < 400; ++i) spheres.push_back({0, 0, 0, 1}), ids.push_back(i);
  DistributedInput in;
  in.spheres = spheres;
  in.ids = ids;
  DistributedResult out;
  const Status st = det.detect(in, out);
  expect_same_failure_everywhere(st, ErrorKind::pair_cap, "rank " + std::to_string(k - 1) + ":");
}

TEST(DistributedDetector, AgreeNamesTheFirstFailingRank) {
  const int rank = world_rank();
  const Status mine = rank == 0 ? Status() : Status::failure(ErrorKind::io_failure, "cannot read x.csv");
  const Status st = viscd::mpi::agree(MPI_COMM_WORLD, mine);
  if (world_size() == 1) {
    EXPECT_TRUE(st.ok());
  } else {
    expect_same_failure_everywhere(st, ErrorKind::io_failure, "rank 1: cannot read x.csv");
  }
}

TEST(DistributedDetector, StatsCountGhostsAndBytes) {
  const int k = world_size();
  const Scene s = make_scene(Layout::uniform, 1000, 0, false, false, 11);
  DistributedDetector det(MPI_COMM_WORLD);
  const DistributedResult out = check_frame(det, s, "stats");
  const Share m = share_of(s, det.rank());
  EXPECT_EQ(out.stats.objects, m.ids.size());
  EXPECT_EQ(out.local.objects, out.stats.objects + out.stats.ghosts_received);
  EXPECT_TRUE(out.stats.ids_checked);
  std::uint64_t sent = out.stats.ghosts_sent, received = out.stats.ghosts_received, s_all = 0, r_all = 0;
  MPI_Allreduce(&sent, &s_all, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  MPI_Allreduce(&received, &r_all, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(s_all, r_all);
  if (k == 1) {
    EXPECT_EQ(out.stats.ghosts_received, 0u);
  } else {
    EXPECT_GT(r_all, 0u);  // neighbouring slabs of 3-unit spheres always share some
    EXPECT_LT(r_all, s.size());
  }
  // The same ids again: not checked again.
  DistributedResult again;
  EXPECT_TRUE(det.detect(m.input(), again).ok());
  EXPECT_FALSE(again.stats.ids_checked);
  // As many ids as before, one of them now another object's: seen, and checked again.
  Share changed = m;
  const int last = k - 1;
  if (det.rank() == last && !changed.ids.empty())
    changed.ids.back() = s.ids[0] == changed.ids.back() ? s.ids[1] : s.ids[0];
  int any = det.rank() == last && !changed.ids.empty() ? 1 : 0, all = 0;
  MPI_Allreduce(&any, &all, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  if (all != 0)
    expect_same_failure_everywhere(det.detect(changed.input(), again), ErrorKind::invalid_input, "given twice");
}

}  // namespace

namespace {
/// What a rank other than 0 prints: its failures only, each with its rank.
class FailurePrinter : public ::testing::EmptyTestEventListener {
  void OnTestPartResult(const ::testing::TestPartResult& r) override {
    if (r.failed())
      std::fprintf(stderr, "[rank %d] %s:%d: failure\n%s\n", world_rank(), r.file_name() ? r.file_name() : "?",
                   r.line_number(), r.summary());
  }
};
}  // namespace

// MPI around GoogleTest: rank 0 prints as usual, the other ranks only their failures.
int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  ::testing::InitGoogleTest(&argc, argv);
  if (world_rank() != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
    listeners.Append(new FailurePrinter);
  }
  int failed = RUN_ALL_TESTS();
  int any = 0;
  MPI_Allreduce(&failed, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  if (any != 0 && world_rank() == 0 && failed == 0) std::fprintf(stderr, "a test failed on another rank\n");
  MPI_Finalize();
  return any;
}
