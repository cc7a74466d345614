// mktree-mpi: the sharded store over MPI ranks (docs/shards.md, "On MPI ranks").
//   mpirun -n R mktree-mpi SCENE... -o MANIFEST --shards K [--backend hdf5|pagefile] [--threads N]
//                          [--round-bytes B] [-q]
//   mpirun -n R mktree-mpi query MANIFEST --queries FILE [--exact] [--cold] [--threads N] [--cache-pages N]
//   ... mpirun -n R mktree-mpi clash MANIFEST [--clearance C] [--touch-tolerance T] [--max-pairs N] ...
// Each command parses its own command line with CLI11 (tools/mpi/mpi_cli.h).
#include <mpi.h>

#include <cstring>

#include "tools/mpi/mpi_util.h"

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  const int rc =
      argc > 1 && std::strcmp(argv[1], "query") == 0   ? mktree::RunQuery(argc - 1, argv + 1, rank, ranks)
      : argc > 1 && std::strcmp(argv[1], "clash") == 0 ? mktree::RunClash(argc - 1, argv + 1, rank, ranks)
                                                       : mktree::RunBuild(argc, argv, rank, ranks);
  MPI_Finalize();
  return rc;
}
