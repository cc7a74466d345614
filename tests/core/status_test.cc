// Status and Result: codes and messages, and the two macros that pass an error up unchanged.
#include "mktree/status.h"

#include <gtest/gtest.h>

#include <memory>
#include <string>

namespace mktree {
namespace {

Result<int> Parse(const std::string& s) {
  if (s.empty()) return Status::InvalidArgument("empty");
  return std::stoi(s);
}

Result<std::unique_ptr<int>> Boxed(int v) {
  if (v < 0) return Status::NotFound("negative");
  return std::make_unique<int>(v);
}

// Declares from a Result, assigns to an existing variable, and moves a move-only value out.
Result<int> SumOfBoxedParses(const std::string& a, const std::string& b) {
  MKTREE_ASSIGN_OR_RETURN(const int x, Parse(a));
  int y = 0;
  MKTREE_ASSIGN_OR_RETURN(y, Parse(b));
  MKTREE_ASSIGN_OR_RETURN(std::unique_ptr<int> boxed, Boxed(x + y));
  return *boxed;
}

Status CheckParses(const std::string& s) {
  MKTREE_ASSIGN_OR_RETURN(auto v, Parse(s));
  return v >= 0 ? Status::Ok() : Status::Corruption("negative " + std::to_string(v));
}

Status Chain(const std::string& s) {
  MKTREE_RETURN_IF_ERROR(CheckParses(s));
  return Status::Internal("reached the end");
}

TEST(StatusTest, ToStringNamesTheCode) {
  EXPECT_EQ(Status::Ok().ToString(), "ok");
  EXPECT_EQ(Status::Corruption("f.mkt: page 3: checksum mismatch").ToString(),
            "corruption: f.mkt: page 3: checksum mismatch");
  EXPECT_EQ(Status::IOError("x").ToString(), "I/O error: x");
}

TEST(StatusTest, AssignOrReturnGivesTheValueOrTheErrorUnchanged) {
  auto sum = SumOfBoxedParses("2", "40");
  ASSERT_TRUE(sum.ok()) << sum.status().ToString();
  EXPECT_EQ(*sum, 42);

  auto bad = SumOfBoxedParses("2", "");
  EXPECT_EQ(bad.status().code(), Status::Code::kInvalidArgument);
  EXPECT_EQ(bad.status().message(), "empty");
  EXPECT_EQ(SumOfBoxedParses("2", "-5").status().code(), Status::Code::kNotFound);

  // In a function that returns a Status.
  EXPECT_TRUE(CheckParses("7").ok());
  EXPECT_EQ(CheckParses("").code(), Status::Code::kInvalidArgument);
  EXPECT_EQ(CheckParses("-1").message(), "negative -1");
}

TEST(StatusTest, ReturnIfErrorPassesTheFirstErrorOn) {
  EXPECT_EQ(Chain("").code(), Status::Code::kInvalidArgument);
  EXPECT_EQ(Chain("-3").ToString(), "corruption: negative -3");
  EXPECT_EQ(Chain("3").code(), Status::Code::kInternal);
}

// Status copies only a failure's message (an ok one has none); copies and assignments keep code and text.
TEST(StatusTest, CopiesAndAssignmentsKeepCodeAndMessage) {
  const Status failed = Status::IOError("store.mkt: page 3: short read");
  Status copy(failed);
  EXPECT_EQ(copy.ToString(), "I/O error: store.mkt: page 3: short read");
  Status assigned = Status::Ok();
  assigned = failed;
  EXPECT_EQ(assigned.code(), Status::Code::kIOError);
  EXPECT_EQ(assigned.message(), failed.message());
  assigned = Status::Ok();  // an ok Status over a failed one leaves no message behind
  EXPECT_TRUE(assigned.ok());
  EXPECT_EQ(assigned.message(), "");
  EXPECT_EQ(assigned.ToString(), "ok");
  Status self = failed;
  const Status& alias = self;
  self = alias;
  EXPECT_EQ(self.message(), failed.message());
  Status moved(std::move(copy));
  EXPECT_EQ(moved.message(), failed.message());
}

}  // namespace
}  // namespace mktree
