// Helpers of mktree-mpi (tools/mpi): byte vectors gathered and broadcast over MPI_COMM_WORLD, and the
// little-endian packing of what the ranks send each other.
#pragma once

#include <mpi.h>

#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "engine/ingest/distributed_build.h"  // RankOfShard
#include "engine/query/store_database.h"
#include "engine/shard/manifest.h"
#include "engine/shard/rank_message.h"
#include "mktree/database.h"

namespace mktree {

// Bytes from one rank to all (root's vector, resized on the others).
inline void Broadcast(std::vector<uint8_t>* bytes) {
  uint64_t n = bytes->size();
  MPI_Bcast(&n, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
  bytes->resize(n);
  MPI_Bcast(bytes->data(), static_cast<int>(n), MPI_BYTE, 0, MPI_COMM_WORLD);
}

// Every rank's bytes, on rank 0, one vector per rank.
inline std::vector<std::vector<uint8_t>> Gather(const std::vector<uint8_t>& mine, int rank, int ranks) {
  const int n = static_cast<int>(mine.size());
  std::vector<int> sizes(ranks), offsets(ranks);
  MPI_Gather(&n, 1, MPI_INT, sizes.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::vector<uint8_t> all;
  if (rank == 0) {
    int at = 0;
    for (int r = 0; r < ranks; ++r) offsets[r] = std::exchange(at, at + sizes[r]);
    all.resize(at);
  }
  MPI_Gatherv(mine.data(), n, MPI_BYTE, all.data(), sizes.data(), offsets.data(), MPI_BYTE, 0,
              MPI_COMM_WORLD);
  std::vector<std::vector<uint8_t>> out;
  if (rank == 0)
    for (int r = 0; r < ranks; ++r)
      out.emplace_back(all.begin() + offsets[r], all.begin() + offsets[r] + sizes[r]);
  return out;
}

// Whether every rank's `ok` holds.
inline bool AllOk(bool ok) {
  int mine = ok ? 1 : 0, all = 0;
  MPI_Allreduce(&mine, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  return all == 1;
}

// The commands (tools/mpi/mpi_build.cc, mpi_query.cc, mpi_clash.cc), on every rank after MPI_Init; the exit
// status.
int RunBuild(int argc, char** argv, int rank, int ranks);
int RunQuery(int argc, char** argv, int rank, int ranks);
int RunClash(int argc, char** argv, int rank, int ranks);

}  // namespace mktree
