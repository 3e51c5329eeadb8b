#pragma once
// The check that global ids are unique over every rank's moving and static objects.

#include <mpi.h>

#include <cstdint>
#include <span>

#include "mpi/comm.hpp"
#include "viscd/result.hpp"

namespace viscd::mpi::detail {

/// Collective: every id goes to the rank a hash of it names; each rank sorts what it received and
/// looks for an id given twice. Fails on every rank alike (invalid_input, naming the id and the
/// two objects: their ranks and indices) when one is; `moving` and `statics` are this rank's ids.
Status check_global_ids(MPI_Comm comm, ByteTypes& types, std::span<const std::uint64_t> moving,
                        std::span<const std::uint64_t> statics, Traffic& traffic);

}  // namespace viscd::mpi::detail
