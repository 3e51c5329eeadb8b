#include "mpi_session.hpp"

#include <cstdio>
#include <cstdlib>
#include <string>

#ifdef VISCD_HAVE_MPI
#include <mpi.h>
#endif

namespace viscd::app {
namespace {
bool g_active = false;
int g_rank = 0, g_size = 1;
}  // namespace

bool launched_by_mpi() {
  return std::getenv("OMPI_COMM_WORLD_SIZE") != nullptr || std::getenv("PMIX_RANK") != nullptr ||
         std::getenv("PMI_SIZE") != nullptr;
}

int launched_ranks() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"})
    if (const char* v = std::getenv(name)) {
      const int k = std::atoi(v);
      if (k > 0) return k;
    }
  return 1;
}

MpiSession::MpiSession(int& argc, char**& argv) {
#ifdef VISCD_HAVE_MPI
  if (!launched_by_mpi()) return;
  int provided = 0;
  if (MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) return;
  g_active = true;
  MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
  MPI_Comm_size(MPI_COMM_WORLD, &g_size);
  if (g_rank != 0) {  // rank 0 speaks for all
    (void)!std::freopen("/dev/null", "w", stdout);
    (void)!std::freopen("/dev/null", "w", stderr);
  }
#else
  (void)argc;
  (void)argv;
#endif
}

MpiSession::~MpiSession() {
#ifdef VISCD_HAVE_MPI
  if (g_active) {
    std::fflush(stdout);
    MPI_Finalize();
  }
#endif
}

bool MpiSession::active() { return g_active; }
int MpiSession::rank() { return g_rank; }
int MpiSession::size() { return g_size; }

}  // namespace viscd::app
