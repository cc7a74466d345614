// The ranks' exchange of the distributed build (engine/shard/rank_exchange.h) over MPI_COMM_WORLD, after
// MPI_Init. Thread-safety: the calling rank's main thread only.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/shard/rank_exchange.h"

namespace mktree {

class MpiExchange final : public RankExchange {
 public:
  MpiExchange(int rank, int ranks) : rank_(rank), ranks_(ranks) {}

  int rank() const override { return rank_; }
  int ranks() const override { return ranks_; }
  std::vector<std::vector<uint8_t>> AllToAll(const std::vector<std::vector<uint8_t>>& send) override;
  std::vector<std::vector<uint8_t>> Gather(const std::vector<uint8_t>& mine) override;
  void Broadcast(std::vector<uint8_t>* bytes) override;
  std::vector<uint64_t> AllGather(const std::vector<uint64_t>& mine) override;
  uint64_t ExclusiveSum(uint64_t value) override;
  uint64_t Sum(uint64_t value) override;
  uint64_t Min(uint64_t value) override;
  double Max(double value) override;
  void Send(int to, const std::vector<uint8_t>& bytes) override;
  std::vector<uint8_t> Receive(int from) override;

 private:
  int rank_, ranks_;
};

}  // namespace mktree
