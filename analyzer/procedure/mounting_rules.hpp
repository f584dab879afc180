#pragma once
// The rules of blocks 5-6 that depend on what kind of cases a mounting holds: which terms IEEE
// Std 1293 leaves out of its fit, in what order the mountings are estimated, and which bias is
// handed from one mounting to another. The mounting stage (mounting_stage.cpp), the procedure's composition
// (pipeline.cpp) and the live solver
// (online/live_solver.cpp, online/live_estimate.cpp) both call these; neither states them.
#include <cstddef>
#include <span>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// What the rules need to know of a mounting's cases.
struct MountingKind {
  bool rotation_table = false;   // one of its cases is on the rotation table
  bool shaker_only = true;       // every one of its cases is on the shaker
  /// A case of the mounting.
  void add_case(dataset::CaseKind kind) {
    rotation_table = rotation_table || kind == dataset::CaseKind::RotationTable;
    shaker_only = shaker_only && kind == dataset::CaseKind::Shaker;
  }
};

/// Paper section 3.2 after IEEE Std 1293, each part switchable (the sparse-selection study turns
/// them off to see what selection alone does).
struct Ieee1293Rules {
  /// 12.3.5.7: on a rotation table a_p^2 and a_o^2 cannot be estimated together with the bias
  /// and a_i^2 (a_i^2 + a_p^2 + a_o^2 = g^2): they are left out of rotation-table mountings.
  bool rotation_table = true;
  /// On the shaker the bias is confounded with the other parameters (gravity is constant in each
  /// orientation): a shaker-only mounting leaves it out and takes the bias another mounting
  /// determined, subtracted from its output. Without one (a shaker-only plan) the bias stays, and
  /// the data's rank decides whether it is determined; an undetermined bias is named as such.
  bool shaker = true;
};

/// Whether the rules leave `term` out of a mounting's external-and-sensor-frame fit (eq. 2);
/// `bias_supplied`: another mounting determined the bias and this one takes it (takes_bias).
[[nodiscard]] bool ieee_1293_excluded(const ident::Term& term, const MountingKind& kind, bool bias_supplied,
                                      const Ieee1293Rules& rules);

/// Whether a mounting takes the bias an earlier mounting determined.
[[nodiscard]] bool takes_bias(const MountingKind& kind, const Ieee1293Rules& rules);

/// Whether a mounting's fitted bias is handed on to the mountings that take one: only from a
/// mounting whose cases determine it (not shaker-only).
[[nodiscard]] bool hands_on_bias(const MountingKind& kind);

/// The order blocks 5-6 estimate the mountings in (indices into `kinds`): those that determine
/// the bias first, so that the shaker-only ones after them can take it; otherwise as given.
[[nodiscard]] std::vector<std::size_t> mounting_order(std::span<const MountingKind> kinds);

}  // namespace inertia::procedure
