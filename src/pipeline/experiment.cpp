#include "hpcm/experiment.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "pipeline/format_number.hpp"

namespace hpcm {

const char* check_status_name(CheckStatus s) {
  switch (s) {
    case CheckStatus::Held: return "held";
    case CheckStatus::Failed: return "failed";
    case CheckStatus::NotApplicable: return "not_applicable";
  }
  return "failed";
}

bool ExperimentResult::all_hold() const {
  return std::none_of(checks.begin(), checks.end(), [](const Check& c) { return c.failed(); });
}

int ExperimentResult::count(CheckStatus s) const {
  return static_cast<int>(std::count_if(checks.begin(), checks.end(), [s](const Check& c) { return c.status == s; }));
}

std::string motion_checks_not_applicable(Int3 dims) {
  int d[3] = {dims.x, dims.y, dims.z};
  std::sort(d, d + 3);
  if (d[1] >= kMotionLatticeMin) return {};  // the two longest axes: d[1] and d[2]
  return "lattice " + std::to_string(dims.x) + "×" + std::to_string(dims.y) + "×" + std::to_string(dims.z) +
         " below " + std::to_string(kMotionLatticeMin) + " along its two longest axes";
}

FarFieldSplit::FarFieldSplit(const Model& model, Index centre, float distance)
    : code_(static_cast<std::size_t>(model.size()), -1), distance_(distance) {
  const Vec3 c = model.rest(centre);
  for (Index i = 0; i < model.size(); ++i) {
    if (!model.counted(i)) continue;  // SPEC §3: the body's elements only
    const bool far = norm(model.rest(i) - c) > distance;
    code_[static_cast<std::size_t>(i)] = static_cast<std::int8_t>(model.tissue[i] + (far ? kTissueCount : 0));
  }
}

void FarFieldSplit::add_frame(const std::vector<Vec3>& before, const std::vector<Vec3>& after) {
  if (before.size() != code_.size() || after.size() != code_.size())
    throw Error("FarFieldSplit: positions for " + std::to_string(before.size()) + " and " + std::to_string(after.size()) +
                " elements, the model has " + std::to_string(code_.size()));
  TissueSums far{}, total{};
  for (std::size_t i = 0; i < code_.size(); ++i) {
    const int k = code_[i];
    if (k < 0) continue;
    const double speed = norm(after[i] - before[i]);
    total[k % kTissueCount] += speed;
    if (k >= kTissueCount) far[k - kTissueCount] += speed;
  }
  for (int t = 0; t < kTissueCount; ++t) {
    far_[t] += far[t];
    total_[t] += total[t];
  }
}

double far_field_share(const TissueSums& far_sum, const TissueSums& total_sum, int t) {
  return total_sum[t] > 0 ? far_sum[t] / total_sum[t] : -1.0;
}

void table2(const std::vector<FrameReport>& frames, int release, int count, PerTissue& initial, PerTissue& peak,
            PerTissue& auc) {
  initial = peak = auc = PerTissue{};
  for (int f = release; f < std::min<int>(release + count, static_cast<int>(frames.size())); ++f)
    for (int t = 0; t < kTissueCount; ++t) {
      const float v = frames[f].mean_speed[t];
      if (f == release) initial[t] = v;
      peak[t] = std::max(peak[t], v);
      auc[t] += v;
    }
}

namespace {

constexpr int kA = 0, kB = 1, kC = 2;
constexpr int kSkin = static_cast<int>(Tissue::SkinFat), kMuscle = static_cast<int>(Tissue::MuscleOrgan),
              kBone = static_cast<int>(Tissue::Bone);

bool finite_state(const State& s) {
  for (std::size_t i = 0; i < s.disp.size(); ++i)
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(s.disp[i][a]) || !std::isfinite(s.vel[i][a])) return false;
  return true;
}

/// How far any element lies outside the boundary box [-margin, N - 1 + margin], from its
/// position X0 + u in double.
float boundary_excess(const Model& m, const State& s, float margin) {
  const Int3 d = m.dims;
  const double hi[3] = {d.x - 1.0 + margin, d.y - 1.0 + margin, d.z - 1.0 + margin};
  double e = 0;
  for (Index i = 0; i < static_cast<Index>(s.disp.size()); ++i) {
    const Vec3 u = s.disp[static_cast<std::size_t>(i)];
    // An element displaced by at most the margin along every axis lies inside the box (its rest
    // position is on the lattice): only the others are placed in double. NaN takes the long way.
    if (std::fabs(u.x) <= margin && std::fabs(u.y) <= margin && std::fabs(u.z) <= margin) continue;
    const Point3 p = position_of(m, i, u);
    for (int a = 0; a < 3; ++a) e = std::max({e, -margin - p[a], p[a] - hi[a]});
  }
  return static_cast<float>(e);
}

ConditionResult run_condition(const Model& model, Params params, DampingMode mode, const ExperimentOptions& opt,
                              Index centre, int cond_index, int release, int recorded, float far_distance) {
  ConditionResult r;
  r.mode = mode;
  r.label = std::string(1, static_cast<char>('A' + cond_index));
  params.dynamics.mode = mode;
  Simulation sim(model, params, opt.backend);
  ScenarioPlayer player(opt.scenario, sim);
  r.centre_rest = sim.model().rest(centre);
  const int total = opt.scenario.frames + opt.settle_frames;
  int done = 0;
  StepOptions so;
  so.link_violation = true;
  so.cell_jacobian = true;
  auto integrity = [&](const FrameReport& f) {
    r.max_link_violation = std::max(r.max_link_violation, f.max_link_violation);
    r.min_cell_jacobian = std::min(r.min_cell_jacobian, f.min_cell_jacobian);
    r.max_folded_cells = std::max(r.max_folded_cells, f.folded_cells);
    r.folded.add(f);
  };
  LimitedPullTracker limited(opt.scenario);
  // SPEC §8.8: speeds of the recorded frames split by distance from the grab centre, from the
  // frame-end positions (the frame before the release is the first one kept).
  FarFieldSplit far_field(model, centre, far_distance);
  std::vector<Vec3> previous;
  if (release == 0) previous = State::rest(model).disp;
  while (!player.done()) {
    const FrameReport f = player.step(so);
    if (auto ended = limited.after_frame(f, sim.tool_offset(), sim.requested_offset()))
      r.limited_pulls.push_back(std::move(*ended));
    r.frames.push_back(f);
    integrity(f);
    r.max_requested_offset = std::max(r.max_requested_offset, f.requested_offset);
    r.max_achieved_offset = std::max(r.max_achieved_offset, f.grab_offset);
    if (f.tool_limited && r.first_limited_frame < 0) r.first_limited_frame = f.frame;
    r.centre_displacement.push_back(sim.displacement(centre));
    const State& s = sim.state();
    r.centre_velocity.push_back(s.vel[static_cast<std::size_t>(centre)]);
    const int frame = static_cast<int>(r.frames.size()) - 1;
    if (frame >= release && frame < release + recorded) far_field.add_frame(previous, s.disp);
    if (frame >= release - 1 && frame < release + recorded - 1) previous = s.disp;
    if (r.finite && !finite_state(s)) r.finite = false;
    r.max_boundary_excess = std::max(r.max_boundary_excess, boundary_excess(model, s, params.dynamics.margin));
    if (opt.progress) opt.progress(cond_index, ++done, total);
  }
  r.far_speed_sum = far_field.far_sum();
  r.total_speed_sum = far_field.total_sum();
  if (auto ended = limited.finish()) r.limited_pulls.push_back(std::move(*ended));
  double cm = 0, in = 0, sn = 0, st = 0;
  for (const auto& f : r.frames) {
    cm += f.chainmail_ms;
    in += f.inertia_ms;
    sn += f.snapshot_ms;
    st += f.sim_total_ms;
  }
  const double n = std::max<std::size_t>(1, r.frames.size());
  r.chainmail_ms = cm / n;
  r.inertia_ms = in / n;
  r.snapshot_ms = sn / n;
  r.sim_total_ms = st / n;
  // SPEC §8.5: after release plus settle_frames idle frames every element is (nearly) still.
  sim.release();
  for (int k = 0; k < opt.settle_frames; ++k) {
    const bool last = k + 1 == opt.settle_frames;
    so.speeds = last;
    const FrameReport fr = sim.step(so);
    integrity(fr);
    if (last) r.settle_max_speed = *std::max_element(fr.max_speed.begin(), fr.max_speed.end());
    if (opt.progress) opt.progress(cond_index, ++done, total);
  }
  r.settle_frames = opt.settle_frames;
  const State& s = sim.state();
  if (r.finite && !finite_state(s)) r.finite = false;
  r.max_boundary_excess = std::max(r.max_boundary_excess, boundary_excess(model, s, params.dynamics.margin));
  for (Index i = 0; i < model.size(); ++i)
    if (model.tissue[i] == kBone && model.counted(i)) r.max_bone_velocity = std::max(r.max_bone_velocity, norm(s.vel[i]));
  return r;
}

Check make_check(std::string name, std::string spec, bool holds, double value, double threshold, std::string what) {
  return Check{std::move(name), std::move(spec), holds ? CheckStatus::Held : CheckStatus::Failed, value, threshold,
               std::move(what), {}};
}

void not_applicable(Check& c, std::string reason) {
  c.status = CheckStatus::NotApplicable;
  c.reason = std::move(reason);
}

/// SPEC §8 item of a motion check: required only on lattices large enough to swing (8.1-8.4,
/// 8.8). C_bone_velocity_zero is a property of the velocity layer, not of the motion: held everywhere.
bool motion_check(const Check& c) {
  if (c.name == "C_bone_velocity_zero") return false;
  return c.spec == "8.1" || c.spec == "8.2" || c.spec == "8.3" || c.spec == "8.4" || c.spec == "8.8";
}

std::string figure(double v) { return detail::format_number(v, "%.3g"); }

/// a / b as a check figure: +inf when b is 0 and a is not (written as JSON null), 0 when both are.
double ratio(double a, double b) {
  if (b > 0) return a / b;
  return a > 0 ? std::numeric_limits<double>::infinity() : 0.0;
}

}  // namespace

ExperimentResult run_experiment(const Model& model, const Params& params, const ExperimentOptions& options) {
  // Millimetre keyframes become lattice units once, here, for every condition.
  ExperimentOptions opt = options;
  opt.scenario = options.scenario.in_lattice_units(model);
  params.validate();
  opt.scenario.validate(model);
  if (opt.scenario.grabs.empty()) throw Error("experiment: the scenario has no grab");
  if (opt.settle_frames < 1) throw Error("experiment: settle_frames must be >= 1");
  ExperimentResult res;
  res.params = params;
  res.dims = model.dims;
  res.elements = model.size();
  res.body = model.body;
  const auto& g0 = opt.scenario.grabs.back();
  for (const GrabAction& g : opt.scenario.grabs)
    check_lattice_extent(model, widest_grab_radius(g, model, params.solver.grab_radius), "experiment: the scenario's grab");
  res.grab_centre = g0.centre ? model.index(g0.centre->x, g0.centre->y, g0.centre->z) : paper_grab_centre(model);
  res.release_frame = opt.scenario.last_release_frame();
  res.recorded_frames = opt.scenario.frames - res.release_frame;
  if (res.recorded_frames < 2) throw Error("experiment: the scenario must record at least 2 frames after the last release");

  const DampingMode modes[3] = {DampingMode::None, DampingMode::Simple, DampingMode::Viscoelastic};
  for (int c = 0; c < 3; ++c) {
    res.conditions.push_back(run_condition(model, params, modes[c], opt, res.grab_centre, c, res.release_frame,
                                           res.recorded_frames, res.far_field_distance));
    auto& cr = res.conditions.back();
    table2(cr.frames, res.release_frame, res.recorded_frames, cr.initial, cr.peak, cr.auc);
  }

  const int rel = res.release_frame;
  // The pull direction: the last grab's final offset.
  Vec3 pull = g0.path.empty() ? Vec3{0, -1, 0} : g0.path.back().offset;
  const float pl = norm(pull);
  pull = pl > 0 ? (1.0f / pl) * pull : Vec3{0, -1, 0};
  auto along = [&](const ConditionResult& cr, int f) { return dot(cr.centre_displacement[f], pull); };

  // 8.1: condition A does not overshoot: after release the grab centre never passes rest
  // (opposite to the pull), and its distance from rest never increases from one frame to the
  // next. Both, because over-relaxation can carry the centre past rest within a single frame,
  // which leaves the distance smaller than before and is seen only from the side it ends on.
  {
    const auto& a = res.conditions[kA];
    double worst = 0;
    for (int f = rel; f < static_cast<int>(a.centre_displacement.size()); ++f) {
      const float prev = norm(a.centre_displacement[f - 1]), cur = norm(a.centre_displacement[f]);
      worst = std::max<double>(worst, cur - prev);
      worst = std::max<double>(worst, -along(a, f));
    }
    res.checks.push_back(make_check("A_no_overshoot", "8.1", worst <= 1e-6, worst, 1e-6,
                                    "after release, the grab centre's largest distance past rest (opposite to the pull) "
                                    "or largest frame-to-frame increase of its distance from rest (lattice units)"));
  }
  // 8.2: B and C overshoot rest and oscillate: the grab centre's velocity along the pull axis
  // changes sign at least twice. Only swings larger than 1 % of the pull count (a reversal is
  // confirmed once the centre has come back from its last extreme by that much), so rounding
  // jitter and small rebounds do not.
  for (int c : {kB, kC}) {
    const auto& cr = res.conditions[c];
    double overshoot = 0;
    for (int f = rel; f < static_cast<int>(cr.centre_displacement.size()); ++f)
      overshoot = std::max<double>(overshoot, -along(cr, f));  // past rest, away from the pull
    const double swing = 0.01 * std::max(cr.max_achieved_offset, 1e-6f);
    int changes = 0, dir = 0;
    double extreme = along(cr, rel - 1);
    for (int f = rel; f < static_cast<int>(cr.centre_displacement.size()); ++f) {
      const double a = along(cr, f);
      if (dir >= 0 && a > extreme) {
        if (dir == 0 && a - extreme < swing) continue;
        extreme = a;
        dir = 1;
      } else if (dir <= 0 && a < extreme) {
        if (dir == 0 && extreme - a < swing) continue;
        extreme = a;
        dir = -1;
      } else if (dir != 0 && std::abs(a - extreme) > swing) {
        ++changes;  // came back from the extreme by more than the swing: a confirmed reversal
        dir = -dir;
        extreme = a;
      }
    }
    res.checks.push_back(make_check(cr.label + "_overshoot", "8.2", overshoot > 1e-3, overshoot, 1e-3,
                                    "largest distance of the grab centre beyond rest, opposite to the pull, after release (lattice units)"));
    res.checks.push_back(make_check(cr.label + "_velocity_sign_changes", "8.2", changes >= 2, changes, 2,
                                    "reversals of the grab centre along the pull axis after release, counting only swings "
                                    "larger than 1 % of the achieved pull"));
  }
  // 8.3: C damps more than B, and C's skin&fat motion settles: from some frame on, its mean
  // speed stays below 5 % of its peak (for at least the last 10 recorded frames).
  {
    const auto &b = res.conditions[kB], &c = res.conditions[kC];
    res.checks.push_back(make_check("C_peak_below_B", "8.3", c.peak[kSkin] < b.peak[kSkin], c.peak[kSkin], b.peak[kSkin],
                                    "skin_fat Peak under C (value) must be below Peak under B (threshold)"));
    res.checks.push_back(make_check("C_auc_below_B", "8.3", c.auc[kSkin] < b.auc[kSkin], c.auc[kSkin], b.auc[kSkin],
                                    "skin_fat AUC under C (value) must be below AUC under B (threshold)"));
    const int end = static_cast<int>(c.frames.size());
    double peak = 0;
    for (int f = rel; f < end; ++f) peak = std::max<double>(peak, c.frames[f].mean_speed[kSkin]);
    int settled_from = end;  // first frame from which the speed stays below 5 % of the peak
    while (settled_from > rel && c.frames[settled_from - 1].mean_speed[kSkin] < 0.05 * peak) --settled_from;
    const int after_release = settled_from - rel;
    res.checks.push_back(make_check("C_skin_settles_5pct", "8.3", peak > 0 && end - settled_from >= 10, after_release,
                                    res.recorded_frames - 10,
                                    "frame after release from which the skin_fat mean speed stays below 5 % of its peak "
                                    "to the end of the recording (must leave at least 10 recorded frames)"));
  }
  // 8.4: tissue hierarchy under C, and bone velocity state exactly 0 when bone is massless.
  {
    const auto& c = res.conditions[kC];
    const char* names[3] = {"initial", "peak", "auc"};
    const PerTissue* vals[3] = {&c.initial, &c.peak, &c.auc};
    for (int k = 0; k < 3; ++k) {
      const PerTissue& v = *vals[k];
      const double margin = std::min<double>(v[kSkin] - v[kMuscle], v[kMuscle] - v[kBone]);
      res.checks.push_back(make_check(std::string("C_hierarchy_") + names[k], "8.4", v[kSkin] > v[kMuscle] && v[kMuscle] > v[kBone],
                                      margin, 0.0,
                                      std::string("min(skin_fat - muscle_organ, muscle_organ - bone) of ") + names[k] + " under C; must be > 0"));
    }
    if (params.dynamics.inverse_mass[kBone] == 0.0f)
      res.checks.push_back(make_check("C_bone_velocity_zero", "8.4", c.max_bone_velocity == 0.0f, c.max_bone_velocity, 0.0,
                                      "largest |V| over bone elements under C (bone inverse mass is 0, so it must be exactly 0)"));
  }
  // 8.8: local response under C (the paper's Table 2 and Figure 3): skin&fat moves at least
  // 10 times more than muscle&organ, the far field carries little of each class's AUC, and A's
  // skin&fat hardly moves after release compared with C's.
  {
    const auto &a = res.conditions[kA], &c = res.conditions[kC];
    const double peak_ratio = ratio(c.peak[kSkin], c.peak[kMuscle]), auc_ratio = ratio(c.auc[kSkin], c.auc[kMuscle]);
    res.checks.push_back(make_check("C_skin_muscle_peak_ratio", "8.8", peak_ratio >= 10, peak_ratio, 10,
                                    "skin_fat Peak / muscle_organ Peak under C (body elements; paper: 26)"));
    res.checks.push_back(make_check("C_skin_muscle_auc_ratio", "8.8", auc_ratio >= 10, auc_ratio, 10,
                                    "skin_fat AUC / muscle_organ AUC under C (body elements; paper: 19)"));
    const std::string dist = figure(res.far_field_distance);
    for (int t : {kSkin, kMuscle, kBone}) {
      const double share = far_field_share(c.far_speed_sum, c.total_speed_sum, t);
      Check k = make_check(std::string("C_far_field_share_") + tissue_name(t), "8.8", share >= 0 && share < 0.10,
                           std::max(share, 0.0), 0.10,
                           std::string("share of the ") + tissue_name(t) + " AUC under C after release carried by body elements "
                           "farther than " + dist + " lattice units (rest position) from the grab centre");
      // A class that does not move has no share; bone (inverse mass 0) may be still.
      if (share < 0) not_applicable(k, std::string(tissue_name(t)) + " did not move after release (AUC 0)");
      res.checks.push_back(std::move(k));
    }
    const double a_over_c = ratio(a.auc[kSkin], c.auc[kSkin]);
    res.checks.push_back(make_check("A_skin_auc_below_C", "8.8", c.auc[kSkin] > 0 && a_over_c < 0.10, a_over_c, 0.10,
                                    "skin_fat AUC after release under A / under C (paper: A stays near 0)"));
  }
  // 8.5: finite, within the boundary margin, still after the settle frames.
  for (const auto& cr : res.conditions) {
    res.checks.push_back(make_check(cr.label + "_finite", "8.5", cr.finite, cr.finite ? 0 : 1, 0,
                                    "1 if any position or velocity was NaN or Inf in any frame"));
    res.checks.push_back(make_check(cr.label + "_within_margin", "8.5", cr.max_boundary_excess <= 0, cr.max_boundary_excess, 0,
                                    "largest coordinate beyond the boundary box [-margin, N-1+margin] (lattice units)"));
    res.checks.push_back(make_check(cr.label + "_settled", "8.5", cr.settle_max_speed >= 0 && cr.settle_max_speed < 1e-6,
                                    cr.settle_max_speed, 1e-6,
                                    "largest element speed after release plus " + std::to_string(cr.settle_frames) + " idle frames"));
  }
  // 8.7: integrity on every frame (protocol and settle frames): every link in its box after
  // the ChainMail stage, no folded cell at frame end.
  for (const auto& cr : res.conditions) {
    res.checks.push_back(make_check(cr.label + "_links_in_box", "8.7", cr.max_link_violation <= 1e-5f,
                                    cr.max_link_violation, 1e-5,
                                    "largest link violation after the ChainMail stage over every frame (lattice units)"));
    res.checks.push_back(make_check(cr.label + "_fold_free", "8.7", cr.min_cell_jacobian > 0.0f, cr.min_cell_jacobian, 0.0,
                                    "smallest cell corner Jacobian determinant at the end of any frame; must be > 0"));
  }
  // SPEC §8: the motion checks are held only where the lattice leaves room to swing, and the
  // residual oscillation (8.2) only where the tool achieved a pull of at least 0.5.
  const std::string small_lattice = motion_checks_not_applicable(model.dims);
  for (Check& k : res.checks) {
    if (!motion_check(k)) continue;
    if (!small_lattice.empty()) {
      not_applicable(k, small_lattice);  // the first reason, also for a class that did not move
    } else if (k.spec == "8.2") {
      const ConditionResult& cr = res.conditions[k.name[0] == 'B' ? kB : kC];
      if (cr.max_achieved_offset < kMinSwingPull)
        not_applicable(k, "achieved pull " + figure(cr.max_achieved_offset) + " lattice units, below " +
                              figure(kMinSwingPull));
    }
  }
  return res;
}

}  // namespace hpcm
