#include "tools/mpi/mpi_exchange.h"

#include <mpi.h>

#include <utility>

#include "tools/mpi/mpi_util.h"

namespace mktree {

std::vector<std::vector<uint8_t>> MpiExchange::AllToAll(const std::vector<std::vector<uint8_t>>& out) {
  std::vector<int> send_counts(ranks_), recv_counts(ranks_), send_at(ranks_), recv_at(ranks_);
  for (int q = 0; q < ranks_; ++q) send_counts[q] = static_cast<int>(out[q].size());
  MPI_Alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  std::vector<uint8_t> send, recv;
  for (int q = 0; q < ranks_; ++q) {
    send_at[q] = static_cast<int>(send.size());
    send.insert(send.end(), out[q].begin(), out[q].end());
  }
  int total = 0;
  for (int q = 0; q < ranks_; ++q) recv_at[q] = std::exchange(total, total + recv_counts[q]);
  recv.resize(static_cast<size_t>(total));
  MPI_Alltoallv(send.data(), send_counts.data(), send_at.data(), MPI_BYTE, recv.data(), recv_counts.data(),
                recv_at.data(), MPI_BYTE, MPI_COMM_WORLD);
  std::vector<std::vector<uint8_t>> in(ranks_);
  for (int q = 0; q < ranks_; ++q)
    in[q].assign(recv.begin() + recv_at[q], recv.begin() + recv_at[q] + recv_counts[q]);
  return in;
}

std::vector<std::vector<uint8_t>> MpiExchange::Gather(const std::vector<uint8_t>& mine) {
  return mktree::Gather(mine, rank_, ranks_);
}

void MpiExchange::Broadcast(std::vector<uint8_t>* bytes) { mktree::Broadcast(bytes); }

std::vector<uint64_t> MpiExchange::AllGather(const std::vector<uint64_t>& mine) {
  std::vector<uint64_t> all(mine.size() * static_cast<size_t>(ranks_));
  MPI_Allgather(mine.data(), static_cast<int>(mine.size()), MPI_UINT64_T, all.data(),
                static_cast<int>(mine.size()), MPI_UINT64_T, MPI_COMM_WORLD);
  return all;
}

uint64_t MpiExchange::ExclusiveSum(uint64_t value) {
  uint64_t out = 0;
  MPI_Exscan(&value, &out, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  return rank_ == 0 ? 0 : out;  // MPI_Exscan leaves rank 0's undefined
}

uint64_t MpiExchange::Sum(uint64_t value) {
  uint64_t out = 0;
  MPI_Allreduce(&value, &out, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  return out;
}

uint64_t MpiExchange::Min(uint64_t value) {
  uint64_t out = 0;
  MPI_Allreduce(&value, &out, 1, MPI_UINT64_T, MPI_MIN, MPI_COMM_WORLD);
  return out;
}

double MpiExchange::Max(double value) {
  double out = 0;
  MPI_Allreduce(&value, &out, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  return out;
}

void MpiExchange::Send(int to, const std::vector<uint8_t>& bytes) {
  const uint64_t n = bytes.size();
  MPI_Send(&n, 1, MPI_UINT64_T, to, 0, MPI_COMM_WORLD);
  MPI_Send(bytes.data(), static_cast<int>(n), MPI_BYTE, to, 1, MPI_COMM_WORLD);
}

std::vector<uint8_t> MpiExchange::Receive(int from) {
  uint64_t n = 0;
  MPI_Recv(&n, 1, MPI_UINT64_T, from, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  std::vector<uint8_t> b(n);
  MPI_Recv(b.data(), static_cast<int>(n), MPI_BYTE, from, 1, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  return b;
}

}  // namespace mktree
