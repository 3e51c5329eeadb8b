// `viscd pairs` under mpirun: every rank reads the files, takes a slab of the objects, and the
// distributed detector finds the pairs; rank 0 writes the same pairs file as one process.
#include <mpi.h>

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>
#include <numeric>
#include <utility>

#include "exit_codes.hpp"
#include "input_files.hpp"
#include "pairs_mpi.hpp"
#include "static_objects.hpp"
#include "viscd/io.hpp"
#include "viscd/mpi.hpp"

namespace viscd::app {
namespace {

using mpi::GlobalPair;

float centre(const ObjectTable& t, std::size_t i, int axis) {
  if (t.kind == ShapeKind::box) {
    const Box& b = t.boxes.boxes[i];
    return 0.5f * b.min[axis] + 0.5f * b.max[axis];
  }
  const Sphere& s = t.spheres.spheres[i];
  return axis == 0 ? s.x : axis == 1 ? s.y : s.z;
}

/// Slabs across the axis where the moving objects' centres spread most: the objects in order
/// along it (ties by index), K equal shares; static objects go to the slab their centre lies in.
struct Slabs {
  int axis = 0;
  std::vector<float> cut;  ///< cut[r]: where slab r starts (r >= 1)
  std::vector<int> owner;  ///< each moving object's rank
};

Slabs slabs_of(const ObjectTable& t, int k) {
  Slabs s;
  const std::size_t n = t.size();
  float lo[3], hi[3];
  for (int a = 0; a < 3; ++a) lo[a] = std::numeric_limits<float>::infinity(), hi[a] = -lo[a];
  for (std::size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], centre(t, i, a)), hi[a] = std::max(hi[a], centre(t, i, a));
  for (int a = 1; a < 3; ++a)
    if (n > 0 && hi[a] - lo[a] > hi[s.axis] - lo[s.axis]) s.axis = a;
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::uint32_t a, std::uint32_t b) { return centre(t, a, s.axis) < centre(t, b, s.axis); });
  s.owner.resize(n);
  s.cut.assign(static_cast<std::size_t>(k), 0);
  const auto kk = static_cast<std::uint64_t>(k);
  for (int r = 0; r < k; ++r) {
    const std::uint64_t begin = n * static_cast<std::uint64_t>(r) / kk,
                        end = n * (static_cast<std::uint64_t>(r) + 1) / kk;
    for (std::uint64_t p = begin; p < end; ++p) s.owner[order[p]] = r;
    // An empty slab starts where the next one does.
    s.cut[static_cast<std::size_t>(r)] =
        begin < n ? centre(t, order[begin], s.axis) : std::numeric_limits<float>::infinity();
  }
  return s;
}

int static_owner(const Slabs& s, float c) {
  int owner = 0;
  for (std::size_t r = 1; r < s.cut.size(); ++r)
    if (c >= s.cut[r]) owner = static_cast<int>(r);
  return owner;
}

/// One rank's share of a table: the objects `keep` accepts, in file order, with ids first + index.
struct Share {
  std::vector<Sphere> spheres;
  std::vector<Box> boxes;
  std::vector<Filter> filters;
  std::vector<std::uint8_t> always_active;
  std::vector<std::uint64_t> ids;
};

template <class Keep>
Share share_of(const ObjectTable& t, std::uint64_t first_id, Keep keep) {
  Share m;
  const bool box = t.kind == ShapeKind::box;
  const auto& filters = box ? t.boxes.filters : t.spheres.filters;
  const auto& always = box ? t.boxes.always_active : t.spheres.always_active;
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (!keep(i)) continue;
    if (box)
      m.boxes.push_back(t.boxes.boxes[i]);
    else
      m.spheres.push_back(t.spheres.spheres[i]);
    if (!filters.empty()) m.filters.push_back(filters[i]);
    if (!always.empty()) m.always_active.push_back(always[i]);
    m.ids.push_back(first_id + i);
  }
  return m;
}

nlohmann::json rank_json(const mpi::RankStats& r) {
  return {{"objects", r.objects},
          {"static_objects", r.static_objects},
          {"ghosts_received", r.ghosts_received},
          {"ghosts_sent", r.ghosts_sent},
          {"static_ghosts_received", r.static_ghosts_received},
          {"static_ghosts_sent", r.static_ghosts_sent},
          {"bytes_sent", r.bytes_sent},
          {"bytes_received", r.bytes_received},
          {"pairs", r.pairs},
          {"exchange_ms", r.exchange_ms},
          {"communication_ms", r.communication_ms},
          {"detect_ms", r.detect_ms},
          {"total_ms", r.total_ms}};
}

}  // namespace

int run_pairs_across_ranks(const PairsAcrossRanks& a) {
  MPI_Comm world = MPI_COMM_WORLD;
  int rank = 0, k = 1;
  MPI_Comm_rank(world, &rank);
  MPI_Comm_size(world, &k);

  // Every rank reads the files (the same bytes fail alike; agree() covers a rank that alone cannot).
  Status st;
  ObjectTable table, fixed;
  {
    auto t = read_moving_objects(a.spheres, a.boxes);
    if (!t)
      st = t.status();
    else
      table = std::move(t.value());
  }
  if (st && !a.static_objects.empty()) {
    auto s = read_static_objects(a.static_objects, table.kind, a.boxes.empty() ? "--spheres" : "--boxes", table.size());
    if (!s)
      st = s.status();
    else
      fixed = std::move(s.value());
  }
  std::optional<DetectorChoice> choice;
  if (st) {
    auto c = make_tool_detector(a.request, a.config);
    if (!c)
      st = c.status();
    else
      choice.emplace(std::move(c.value()));
  }
  if (Status s = mpi::agree(world, st); !s) return fail(s.error());

  // This rank's slab, numbered as one process numbers them: moving object i is i, static k is N + k.
  const std::size_t n = table.size();
  const Slabs slabs = slabs_of(table, k);
  const Share mine = share_of(table, 0, [&](std::size_t i) { return slabs.owner[i] == rank; });
  const Share mine_static =
      share_of(fixed, n, [&](std::size_t i) { return static_owner(slabs, centre(fixed, i, slabs.axis)) == rank; });

  const std::string backend = choice->backend;
  mpi::DistributedDetector det(world, std::move(choice->detector));
  st = table.kind == ShapeKind::box ? det.set_static_boxes(mine_static.boxes, mine_static.ids, mine_static.filters)
                                    : det.set_static_spheres(mine_static.spheres, mine_static.ids, mine_static.filters);
  if (!st) st = Status::failure(st.kind(), "--static: " + st.error());
  if (Status s = mpi::agree(world, st); !s) return fail(s.error());
  mpi::DistributedInput in;
  in.spheres = mine.spheres;
  in.boxes = mine.boxes;
  in.ids = mine.ids;
  in.filters = mine.filters;
  in.always_active = mine.always_active;
  mpi::DistributedResult result;
  if (Status s = det.detect(in, result); !s) return fail(s.error());
  std::vector<GlobalPair> all;
  if (Status s = det.gather_pairs(result, all); !s) return fail(s.error());
  std::vector<mpi::RankStats> ranks(rank == 0 ? static_cast<std::size_t>(k) : 0);
  MPI_Gather(&result.stats, sizeof(mpi::RankStats), MPI_BYTE, ranks.data(), sizeof(mpi::RankStats), MPI_BYTE, 0, world);

  // Rank 0 writes both outputs, whole or not at all; every rank ends with its status.
  std::vector<Pair> pairs;
  std::uint64_t hash = 0;
  if (rank == 0) {
    pairs.reserve(all.size());
    for (const GlobalPair& p : all) pairs.push_back({static_cast<std::uint32_t>(p.a), static_cast<std::uint32_t>(p.b)});
    hash = pairs_hash(pairs);
    st = [&]() -> Status {
      auto pairs_file = AtomicFile::create(a.out);
      if (!pairs_file) return pairs_file.status();
      if (Status s = write_pairs_csv(pairs_file.value(), pairs); !s) return s;
      std::optional<AtomicFile> stats_file;
      if (!a.stats.empty()) {
        auto f = AtomicFile::create(a.stats);
        if (!f) return f.status();
        stats_file.emplace(std::move(f.value()));
        nlohmann::json j = {{"ranks", k},
                            {"backend", backend},
                            {"objects", n},
                            {"static_objects", fixed.size()},
                            {"pairs", pairs.size()},
                            {"per_rank", nlohmann::json::array()}};
        for (const auto& r : ranks) j["per_rank"].push_back(rank_json(r));
        if (Status s = stats_file->write(j.dump(2) + "\n"); !s) return s;
      }
      if (Status s = pairs_file.value().commit(); !s) return s;
      if (stats_file)
        if (Status s = stats_file->commit(); !s) return s;
      return {};
    }();
  }
  if (Status s = mpi::agree(world, st); !s) return fail(s.error());

  int rc = kExitOk;
  if (rank == 0) {
    std::uint64_t ghosts = 0;
    for (const auto& r : ranks) ghosts += r.ghosts_received;
    const std::string fixed_count =
        fixed.size() == 0 ? std::string() : " + " + std::to_string(fixed.size()) + " static";
    std::printf("%zu objects%s over %d ranks, %zu pairs, %" PRIu64 " ghosts, hash %016" PRIx64 "\n", n,
                fixed_count.c_str(), k, pairs.size(), ghosts, hash);
    std::printf("wrote %s%s%s\n", printable(a.out, 200).c_str(), a.stats.empty() ? "" : " and ",
                printable(a.stats, 200).c_str());
    if (!a.validate_hash.empty()) rc = check_pairs_hash(a.validate_hash, hash);
  }
  MPI_Bcast(&rc, 1, MPI_INT, 0, world);
  return rc;
}

}  // namespace viscd::app
