#pragma once
// The MPI calls the distributed detector makes, each returning a Status, and the rule that keeps
// ranks in step: every collective is entered by every rank, and a rank that fails between two of
// them says so in the next agree() instead of leaving the others waiting.

#include <mpi.h>

#include <climits>
#include <cstdint>
#include <new>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "viscd/result.hpp"

namespace viscd::mpi::detail {

/// splitmix64's finaliser: spreads ids that count up (the checking rank's hash, fingerprints).
inline std::uint64_t mix64(std::uint64_t x) {
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

/// Ok for MPI_SUCCESS, else backend_failure naming the call and MPI's own text for the code.
Status mpi_status(int rc, const char* call);

/// agree() with or without the "rank R: " prefix (messages that name their ranks themselves).
Status agree(MPI_Comm comm, const Status& local, bool prefix_rank);

/// A committed MPI type of `bytes` contiguous bytes (freed by free_types()).
class ByteTypes {
 public:
  ByteTypes() = default;
  ByteTypes(const ByteTypes&) = delete;
  ByteTypes& operator=(const ByteTypes&) = delete;
  ~ByteTypes();
  /// The type for records of `bytes` bytes; created on first use.
  Status get(int bytes, MPI_Datatype& type);

 private:
  std::vector<std::pair<int, MPI_Datatype>> types_;
};

/// Bytes moved by this rank and the wall time of the calls that moved them, for RankStats.
struct Traffic {
  std::uint64_t sent = 0, received = 0;
  double ms = 0;
};

/// Adds the wall time of its scope to a Traffic's ms.
class TrafficTimer {
 public:
  explicit TrafficTimer(Traffic& t) : t_(t), start_(MPI_Wtime()) {}
  ~TrafficTimer() { t_.ms += (MPI_Wtime() - start_) * 1e3; }
  TrafficTimer(const TrafficTimer&) = delete;
  TrafficTimer& operator=(const TrafficTimer&) = delete;

 private:
  Traffic& t_;
  double start_;
};

/// Sends `send` (records grouped by destination rank, `send_counts[r]` of them for rank r) to
/// every rank and receives every rank's records for this one into `recv` (grouped by source rank,
/// `recv_counts[r]` from rank r). Collective; agrees before every step that could fail on one rank
/// alone (counts past INT_MAX, memory), so that no rank is left in a collective the others skipped.
template <class T>
Status all_to_all(MPI_Comm comm, ByteTypes& types, std::span<const T> send, std::span<const std::uint64_t> send_counts,
                  std::vector<T>& recv, std::vector<int>& recv_counts, Traffic& traffic) {
  const auto k = send_counts.size();
  std::vector<int> counts(k), displs(k), rdispls(k);
  recv_counts.assign(k, 0);
  MPI_Datatype type = MPI_DATATYPE_NULL;
  Status local = types.get(static_cast<int>(sizeof(T)), type);
  std::uint64_t at = 0;
  for (std::size_t r = 0; local && r < k; ++r) {
    if (send_counts[r] > INT_MAX || at > INT_MAX)
      local = Status::failure(ErrorKind::unsupported_input,
                              "more than 2^31 - 1 records for one exchange (" + std::to_string(send_counts[r]) + ")");
    counts[r] = static_cast<int>(send_counts[r]);
    displs[r] = static_cast<int>(at);
    at += send_counts[r];
  }
  if (Status s = agree(comm, local, true); !s) return s;
  const TrafficTimer timer(traffic);  // the counts, the agreement on them and the records
  if (Status s =
          mpi_status(MPI_Alltoall(counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, comm), "MPI_Alltoall");
      !s)
    return s;
  std::uint64_t total = 0;
  for (std::size_t r = 0; r < k; ++r) {
    rdispls[r] = static_cast<int>(total);
    total += static_cast<std::uint64_t>(recv_counts[r]);
    if (total > INT_MAX && local)
      local = Status::failure(ErrorKind::unsupported_input, "more than 2^31 - 1 records received in one exchange");
  }
  if (local) {
    try {
      recv.resize(total);
    } catch (const std::bad_alloc&) {
      local = Status::failure(ErrorKind::out_of_memory, "out of memory receiving " + std::to_string(total) +
                                                            " records of " + std::to_string(sizeof(T)) + " bytes");
    }
  }
  if (Status s = agree(comm, local, true); !s) return s;
  traffic.sent += at * sizeof(T);
  traffic.received += total * sizeof(T);
  return mpi_status(MPI_Alltoallv(send.data(), counts.data(), displs.data(), type, recv.data(), recv_counts.data(),
                                  rdispls.data(), type, comm),
                    "MPI_Alltoallv");
}

}  // namespace viscd::mpi::detail
