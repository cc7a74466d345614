// The focus of a self-clash (MultiClashScope::focus): the global ids of the objects a pair must touch,
// and where each part's tree may hold them (FocusMarks), found from the objects' records so that no leaf
// page is read for it. Thread safety: immutable once made (any number of threads may ask it).
#pragma once

#include <cstdint>
#include <vector>

#include "engine/clash/leaf_pairs.h"
#include "engine/clash/part_numbering.h"
#include "mktree/status.h"

namespace mktree::clash {

class ClashFocus {
 public:
  // The focus on `ids` (global, any order, repeats allowed): per part the visible objects among them
  // (ids found by binary search in its id map, hidden ones left out), their records read in id order
  // straight from the store (each record page once, not through the page cache: the clash's page counts
  // stay its leaves'), each one's leaf and the leaf filter positions whose quantised boxes contain its
  // record's box (every position of the leaf when none does), then the nodes above those leaves.
  // Errors: a damaged record page, or a record that names no leaf of the tree.
  // With `partner` (may be null): the same for the partner set (MultiClashScope::partner).
  static Result<ClashFocus> Make(const PartNumbering& parts, std::vector<ObjectId> ids,
                                 const std::vector<ObjectId>* partner = nullptr);

  // Is global id `id` in the focus?
  bool Holds(ObjectId id) const;
  // Is global id `id` in the partner set? True for every id without one.
  bool HoldsPartner(ObjectId id) const;
  const FocusMarks& marks(size_t part) const { return marks_[part]; }
  // The partner set's marks; null without one (every node and object may be a partner).
  const FocusMarks* partner_marks(size_t part) const {
    return partner_marks_.empty() ? nullptr : &partner_marks_[part];
  }

 private:
  std::vector<ObjectId> ids_;  // increasing
  std::vector<FocusMarks> marks_;
  bool has_partner_ = false;
  std::vector<ObjectId> partner_ids_;  // increasing
  std::vector<FocusMarks> partner_marks_;
};

}  // namespace mktree::clash
