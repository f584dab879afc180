#pragma once
// Which cases share a mounting, and each mounting's cases as blocks 5-6 fit them: turned into the
// nominal case frame, weighted, with the kind of cases the mounting rules look at.
//
// The misalignment of a sensor case relative to the frame its references are given in is one
// unknown per mounting of the sensor. Cases that share a mounting (dataset key `mounting`, e.g. the
// three shaker orientations of Fig. 2, where the fixture is remounted but the sensor is not) are
// estimated together: each case's references are first turned into its nominal case frame
// (a_C = M_E^C a_E), where the shared misalignment is one rotation, and algorithm 2 runs on the
// concatenated cases. A case without a mounting label is a mounting of its own.
#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "analyzer/procedure/mounting_rules.hpp"
#include "analyzer/procedure/pipeline_options.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"
#include "common/frames.hpp"

namespace inertia::procedure {

/// A case as the grouping into mountings sees it.
struct MountingKey {
  std::string name;     // its plan case
  std::string label;    // its `mounting` label ("": none)
  CaseKind kind = CaseKind::Static;
};
using MountingGroups = std::vector<std::pair<std::string, std::vector<std::size_t>>>;

/// Which cases share a mounting (blocks 5-6): the batch pipeline's and the live estimator's one
/// rule. Cases with one `mounting` label share it and an unlabelled case is its own, in order of
/// first appearance; with no label anywhere, an accelerometer's static and thermal poses (two or
/// more) share one mounting "poses", put first (a tumble: the sensor stays in its fixture, which
/// is turned between poses); a gyroscope's cases are one mounting "all cases" (paper section 2.2:
/// its M_C^S is read from the rates of every case). What was inferred goes to `notes`.
MountingGroups group_mountings(const std::vector<MountingKey>& cases, dataset::SensorKind sensor,
                               std::vector<std::string>* notes = nullptr);
/// The same for a dataset's cases (keyed by their plan case).
MountingGroups mountings_of(const dataset::Dataset& data, std::vector<std::string>* notes = nullptr);

/// The kind of each group's cases (mounting_rules.hpp), in the order of `groups`.
std::vector<MountingKind> mounting_kinds(const dataset::Dataset& data, const MountingGroups& groups);

/// A case's batch weight: the weight given for its plan case (itself, or the case it is a piece
/// of: a log split by lost samples); 1 otherwise.
double case_weight(const PipelineOptions& options, const dataset::CaseData& c);

/// One mounting's cases with their references turned into the nominal case frame, so that the
/// shared misalignment is a single M_C^S (with m_ec = I in the copies).
/// A mounting's cases as its fit reads them: the external variables in the nominal case frame
/// (M_E^C a_E), and the output less a bias known from another mounting.
struct MountingCases {
  std::vector<std::size_t> indices;               // dataset case indices
  std::vector<const dataset::CaseData*> cases;    // the dataset's, in that order
  std::vector<double> weights;
  double known_bias = 0.0;                        // taken from the output (0: none)
  MountingKind kind;
};

/// The cases `indices` of `data` as their mounting's fit sees them; `known_bias` (output unit),
/// when given, is subtracted from the output. `data` must outlive the result.
MountingCases mounting_cases(const dataset::Dataset& data, const std::vector<std::size_t>& indices,
                             const PipelineOptions& options, std::optional<double> known_bias);

/// The mounting's cases to stack, each with M_C^S = `m_cs` (M_E^S = M_C^S M_E^C) and read in its
/// nominal case frame.
std::vector<StackInput> stack_inputs(const MountingCases& m, const frames::Dcm& m_cs);

/// [input 1]'[input 1] of one case in its nominal case frame (specific force, or rates for a
/// gyroscope; zero for a gyroscope's case without rates): what the excitation and placement
/// rules read.
Eigen::Matrix4d case_input_gram(const dataset::CaseData& c, dataset::SensorKind sensor);

}  // namespace inertia::procedure
