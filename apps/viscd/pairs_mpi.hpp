#pragma once
// `viscd pairs` across MPI ranks (cmd_pairs_mpi.cpp, built with MPI), and what it shares with the
// one-process run (cmd_pairs.cpp).
#include <cstdint>
#include <string>

#include "detector_choice.hpp"
#include "viscd/config.hpp"

namespace viscd::app {

/// What `viscd pairs` under mpirun needs: its files, the local detector's request and config.
struct PairsAcrossRanks {
  std::string spheres, boxes, static_objects, out, stats, validate_hash;
  Config config;
  DetectorRequest request;
};

/// Runs `viscd pairs` on every rank of MPI_COMM_WORLD (docs/mpi.md): each rank takes a slab of the
/// objects, rank 0 writes the pairs file one process writes. Every rank returns the same exit code.
int run_pairs_across_ranks(const PairsAcrossRanks& args);

/// --validate-hash (16 hex digits, any case) against the pairs' hash: prints "hash matches" and
/// returns kExitOk, or prints the mismatch and returns kExitHashMismatch.
int check_pairs_hash(const std::string& validate_hash, std::uint64_t hash);

}  // namespace viscd::app
