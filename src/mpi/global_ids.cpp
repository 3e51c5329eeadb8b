#include "mpi/global_ids.hpp"

#include <algorithm>
#include <string>
#include <vector>

namespace viscd::mpi::detail {
namespace {

/// An id and where it came from: the rank and the object's index there (kStatic set for a
/// static object).
struct IdEntry {
  std::uint64_t id = 0;
  std::uint32_t rank = 0;
  std::uint32_t index = 0;
};
static_assert(sizeof(IdEntry) == 16);
constexpr std::uint32_t kStatic = 0x80000000u;

std::string name(const IdEntry& e) {
  return "rank " + std::to_string(e.rank) + ((e.index & kStatic) != 0 ? " static object " : " object ") +
         std::to_string(e.index & ~kStatic);
}

}  // namespace

Status check_global_ids(MPI_Comm comm, ByteTypes& types, std::span<const std::uint64_t> moving,
                        std::span<const std::uint64_t> statics, Traffic& traffic) {
  int rank = 0, size = 1;
  if (Status s = mpi_status(MPI_Comm_rank(comm, &rank), "MPI_Comm_rank"); !s) return s;
  if (Status s = mpi_status(MPI_Comm_size(comm, &size), "MPI_Comm_size"); !s) return s;
  const auto k = static_cast<std::size_t>(size);
  std::vector<std::uint64_t> counts(k, 0);
  std::vector<IdEntry> send;
  Status local;
  try {
    for (const std::uint64_t id : moving) ++counts[mix64(id) % k];
    for (const std::uint64_t id : statics) ++counts[mix64(id) % k];
    std::vector<std::uint64_t> at(k, 0);
    for (std::size_t r = 1; r < k; ++r) at[r] = at[r - 1] + counts[r - 1];
    send.resize(moving.size() + statics.size());
    const auto me = static_cast<std::uint32_t>(rank);
    for (std::size_t i = 0; i < moving.size(); ++i)
      send[at[mix64(moving[i]) % k]++] = {moving[i], me, static_cast<std::uint32_t>(i)};
    for (std::size_t i = 0; i < statics.size(); ++i)
      send[at[mix64(statics[i]) % k]++] = {statics[i], me, static_cast<std::uint32_t>(i) | kStatic};
  } catch (const std::bad_alloc&) {
    local = Status::failure(ErrorKind::out_of_memory,
                            "out of memory checking " + std::to_string(moving.size() + statics.size()) + " global ids");
  }
  if (Status s = agree(comm, local, true); !s) return s;
  std::vector<IdEntry> recv;
  std::vector<int> recv_counts;
  if (Status s = all_to_all<IdEntry>(comm, types, send, counts, recv, recv_counts, traffic); !s) return s;
  std::sort(recv.begin(), recv.end(), [](const IdEntry& a, const IdEntry& b) {
    return a.id != b.id ? a.id < b.id : a.rank != b.rank ? a.rank < b.rank : a.index < b.index;
  });
  // The smallest repeated id this rank holds; the lowest rank that finds one speaks for all.
  for (std::size_t i = 1; i < recv.size(); ++i)
    if (recv[i].id == recv[i - 1].id) {
      local = Status::failure(ErrorKind::invalid_input, "global id " + std::to_string(recv[i].id) +
                                                            " is given twice: " + name(recv[i - 1]) + " and " +
                                                            name(recv[i]) + " (ids must be unique over every rank)");
      break;
    }
  return agree(comm, local, false);
}

}  // namespace viscd::mpi::detail
