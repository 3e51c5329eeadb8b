#include "mpi/comm.hpp"

#include <algorithm>

#include "viscd/mpi.hpp"

namespace viscd::mpi {
namespace detail {

Status mpi_status(int rc, const char* call) {
  if (rc == MPI_SUCCESS) return {};
  char text[MPI_MAX_ERROR_STRING] = {};
  int length = 0;
  if (MPI_Error_string(rc, text, &length) != MPI_SUCCESS) length = 0;
  return Status::failure(ErrorKind::backend_failure,
                         std::string(call) + " failed: " + std::string(text, static_cast<std::size_t>(length)));
}

Status agree(MPI_Comm comm, const Status& local, bool prefix_rank) {
  int rank = 0, size = 0;
  if (Status s = mpi_status(MPI_Comm_rank(comm, &rank), "MPI_Comm_rank"); !s) return s;
  if (Status s = mpi_status(MPI_Comm_size(comm, &size), "MPI_Comm_size"); !s) return s;
  // The lowest failing rank speaks for all.
  int mine = local ? size : rank, first = size;
  if (Status s = mpi_status(MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm), "MPI_Allreduce"); !s)
    return local ? s : local;
  if (first == size) return {};
  // Its kind and message (at most 4 KiB of it) go to every rank.
  constexpr std::size_t kMaxMessage = 4096;
  int header[2] = {0, 0};
  std::string message;
  if (rank == first) {
    message = local.error().substr(0, kMaxMessage);
    header[0] = static_cast<int>(local.kind());
    header[1] = static_cast<int>(message.size());
  }
  if (Status s = mpi_status(MPI_Bcast(header, 2, MPI_INT, first, comm), "MPI_Bcast"); !s) return local ? s : local;
  message.resize(static_cast<std::size_t>(std::clamp(header[1], 0, static_cast<int>(kMaxMessage))));
  if (Status s =
          mpi_status(MPI_Bcast(message.data(), static_cast<int>(message.size()), MPI_CHAR, first, comm), "MPI_Bcast");
      !s)
    return local ? s : local;
  const auto kind = static_cast<ErrorKind>(header[0]);
  return Status::failure(kind, prefix_rank ? "rank " + std::to_string(first) + ": " + message : message);
}

ByteTypes::~ByteTypes() {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (finalized) return;  // too late to free; MPI has released them
  for (auto& [bytes, type] : types_) MPI_Type_free(&type);
}

Status ByteTypes::get(int bytes, MPI_Datatype& type) {
  for (const auto& [b, t] : types_)
    if (b == bytes) {
      type = t;
      return {};
    }
  MPI_Datatype made = MPI_DATATYPE_NULL;
  if (Status s = mpi_status(MPI_Type_contiguous(bytes, MPI_BYTE, &made), "MPI_Type_contiguous"); !s) return s;
  if (Status s = mpi_status(MPI_Type_commit(&made), "MPI_Type_commit"); !s) return s;
  types_.emplace_back(bytes, made);
  type = made;
  return {};
}

}  // namespace detail

Status agree(MPI_Comm comm, const Status& local) { return detail::agree(comm, local, true); }

}  // namespace viscd::mpi
