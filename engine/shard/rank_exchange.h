// The collective operations between the ranks of the distributed sharded build
// (engine/ingest/distributed_build.h), without MPI: tools/mpi implements them over MPI_COMM_WORLD, a test
// over threads of one process. Every rank calls the collectives (all but Send and Receive) in the same
// order, as with MPI; Send and Receive pair one rank with another, messages in order.
// Thread-safety: a rank's exchange is used by that rank's thread alone.
#pragma once

#include <cstdint>
#include <vector>

namespace mktree {

class RankExchange {
 public:
  virtual ~RankExchange() = default;

  virtual int rank() const = 0;
  virtual int ranks() const = 0;

  // send[q] to rank q; returns what each rank sent this one, by rank.
  virtual std::vector<std::vector<uint8_t>> AllToAll(const std::vector<std::vector<uint8_t>>& send) = 0;
  // Every rank's bytes on rank 0, by rank; empty on the other ranks.
  virtual std::vector<std::vector<uint8_t>> Gather(const std::vector<uint8_t>& mine) = 0;
  // Rank 0's bytes to every rank (replacing *bytes on the others).
  virtual void Broadcast(std::vector<uint8_t>* bytes) = 0;
  // Every rank's values (as many on each rank), rank after rank, on every rank.
  virtual std::vector<uint64_t> AllGather(const std::vector<uint64_t>& mine) = 0;
  // The sum of the values of the ranks below this one (0 on rank 0).
  virtual uint64_t ExclusiveSum(uint64_t value) = 0;
  // Over every rank, on every rank.
  virtual uint64_t Sum(uint64_t value) = 0;
  virtual uint64_t Min(uint64_t value) = 0;
  virtual double Max(double value) = 0;

  // Point to point: bytes to rank `to`; the next bytes rank `from` sent this one.
  virtual void Send(int to, const std::vector<uint8_t>& bytes) = 0;
  virtual std::vector<uint8_t> Receive(int from) = 0;
};

}  // namespace mktree
