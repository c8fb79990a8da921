// The control panel and the plots of hpcm-viewer. Every change that concerns the simulation
// is sent to the simulation thread as a command; the panel shows the latest published frame.
#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>

#include "param_panel.hpp"
#include "viewer.hpp"

#ifdef HPCM_VIEWER_WITH_IO
#include "hpcm/io.hpp"
#endif
#ifdef HPCM_VIEWER_WITH_CONFIG
#include "hpcm/config.hpp"
#endif

namespace hpcm::viewer {
namespace {

ImU32 series_colour(int tissue) {
  switch (tissue) {
    case 0: return IM_COL32(150, 150, 160, 255);
    case 1: return IM_COL32(240, 200, 110, 255);
    case 2: return IM_COL32(230, 80, 70, 255);
    case 3: return IM_COL32(235, 235, 235, 255);
  }
  return IM_COL32(255, 0, 255, 255);
}

/// A multi-series line plot over the history (newest at the right edge).
void plot_series(const char* id, int series, int count, int capacity, const std::function<float(int, int)>& get,
                 const std::function<ImU32(int)>& colour, const std::function<const char*(int)>& name, ImVec2 size,
                 bool log_scale, const char* unit) {
  ImGui::PushID(id);
  const ImVec2 p0 = ImGui::GetCursorScreenPos();
  ImGui::InvisibleButton("plot", size);
  const ImVec2 p1(p0.x + size.x, p0.y + size.y);
  ImDrawList* dl = ImGui::GetWindowDrawList();
  dl->AddRectFilled(p0, p1, IM_COL32(18, 20, 26, 255));
  dl->AddRect(p0, p1, IM_COL32(80, 82, 95, 255));
  float hi = 0;
  for (int s = 0; s < series; ++s)
    for (int k = 0; k < count; ++k) {
      const float v = get(s, k);
      if (std::isfinite(v)) hi = std::max(hi, v);
    }
  const float top = hi > 0 ? hi * 1.1f : 1.0f;
  const float lo_log = std::log10(std::max(top * 1e-5f, 1e-9f)), hi_log = std::log10(top);
  auto ymap = [&](float v) {
    float t;
    if (log_scale) t = (std::log10(std::max(v, 1e-12f)) - lo_log) / std::max(hi_log - lo_log, 1e-6f);
    else t = v / top;
    t = std::clamp(t, 0.0f, 1.0f);
    return p1.y - 2 - t * (size.y - 22);  // the top 18 px hold the labels
  };
  std::vector<ImVec2> pts;
  const float dx = (size.x - 4) / float(std::max(capacity - 1, 1));
  for (int s = 0; s < series; ++s) {
    pts.clear();
    for (int k = 0; k < count; ++k) {
      const float x = p1.x - 2 - float(count - 1 - k) * dx;
      pts.push_back(ImVec2(x, ymap(get(s, k))));
    }
    if (pts.size() >= 2) dl->AddPolyline(pts.data(), static_cast<int>(pts.size()), colour(s), 0, 1.5f);
  }
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.3g %s%s", double(top), unit, log_scale ? " (log)" : "");
  dl->AddText(ImVec2(p0.x + 4, p0.y + 2), IM_COL32(200, 200, 200, 255), buf);
  float lx = p0.x + 4 + ImGui::CalcTextSize(buf).x + 14;
  for (int s = 0; s < series; ++s) {
    const char* n = name(s);
    dl->AddText(ImVec2(lx, p0.y + 2), colour(s), n);
    lx += ImGui::CalcTextSize(n).x + 10;
  }
  dl->AddLine(ImVec2(p0.x + 1, p0.y + 18), ImVec2(p1.x - 1, p0.y + 18), IM_COL32(50, 52, 62, 255));
  ImGui::PopID();
}

}  // namespace

// ------------------------------------------------------------------------------------------
// plots

void Viewer::draw_plots(float width, float h) {
  const int n = std::min(static_cast<int>(hist_.size()), hist_len_);
  const int off = static_cast<int>(hist_.size()) - n;
  ImGui::Text("mean speed per tissue (lattice units / frame), last %d frames", hist_len_);
  plot_series(
      "speed", kTissueCount, n, hist_len_, [&](int s, int k) { return hist_[static_cast<std::size_t>(off + k)].speed[s]; },
      series_colour, [](int s) { return tissue_name(s); }, ImVec2(width, h), log_speed_, "");
  ImGui::Text("stage times (ms)");
  static const char* stage[4] = {"ChainMail", "Inertia", "Snapshot", "SimTotal"};
  static const ImU32 stage_col[4] = {IM_COL32(90, 160, 255, 255), IM_COL32(240, 120, 200, 255),
                                     IM_COL32(140, 220, 120, 255), IM_COL32(240, 240, 240, 255)};
  plot_series(
      "times", 4, n, hist_len_,
      [&](int s, int k) {
        const FrameSample& x = hist_[static_cast<std::size_t>(off + k)];
        return s == 0 ? x.chainmail : s == 1 ? x.inertia : s == 2 ? x.snapshot : x.total;
      },
      [](int s) { return stage_col[s]; }, [](int s) { return stage[s]; }, ImVec2(width, h), false, "ms");
  ImGui::TextUnformatted(rates_text().c_str());
  const FrameReport& r = shown_->report;
  ImGui::Text("%lld elements | last frame: %s, moved %lld, bricks %lld, sweeps %d/%d",
              static_cast<long long>(shown_->model->size()), r.deform ? "deform" : "idle",
              static_cast<long long>(r.moved_elements), static_cast<long long>(r.active_bricks), r.propagate_sweeps,
              r.relax_sweeps);
}

void Viewer::draw_plots_window() {
  ImGui::SetNextWindowPos(ImVec2(plots_rect_.x, plots_rect_.y));
  ImGui::SetNextWindowSize(ImVec2(plots_rect_.w, plots_rect_.h));
  ImGui::Begin("Plots", nullptr,
               ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse |
                   ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoBringToFrontOnFocus);
  const float w = ImGui::GetContentRegionAvail().x;
  const float h = std::max(60.0f, (ImGui::GetContentRegionAvail().y - 4 * ImGui::GetTextLineHeightWithSpacing()) / 2 - 6);
  draw_plots(w, h);
  ImGui::End();
}

// ------------------------------------------------------------------------------------------
// the control panel

void Viewer::draw_panel() {
  const ImGuiIO& io = ImGui::GetIO();
  ImGui::SetNextWindowPos(ImVec2(0, 0));
  ImGui::SetNextWindowSize(ImVec2(std::min(panel_w_, io.DisplaySize.x * 0.5f), io.DisplaySize.y));
  ImGui::Begin("hpcm-viewer", nullptr,
               ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse |
                   ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoBringToFrontOnFocus);
  ImGui::PushItemWidth(-150);
  panel_run_controls();
  panel_backend();
  panel_views();
  if (!plots_in_cell_ && ImGui::CollapsingHeader("Plots", ImGuiTreeNodeFlags_DefaultOpen))
    draw_plots(ImGui::GetContentRegionAvail().x, 110);
  if (ImGui::CollapsingHeader("Plot settings")) {
    ImGui::SliderInt("history (frames)", &hist_len_, 50, 2000, "%d", ImGuiSliderFlags_AlwaysClamp);
    ImGui::Checkbox("log speed axis", &log_speed_);
  }
  bool changed = panel_solver_and_dynamics();
  changed |= panel_tissue_and_material();
  if (changed) params_pending_ = true;
  // Material and threshold edits rebuild the model: they are applied when the widget is released.
  if (!param_error_.empty()) ImGui::TextColored(ImVec4(1, 0.4f, 0.4f, 1), "%s", param_error_.c_str());
  panel_parameter_file();
  panel_scenario();
  panel_data();
  ImGui::PopItemWidth();
  if (!message_.empty()) {
    ImGui::Separator();
    if (message_error_) ImGui::TextColored(ImVec4(1, 0.45f, 0.4f, 1), "%s", message_.c_str());
    else ImGui::TextWrapped("%s", message_.c_str());
  }
  ImGui::End();
}

void Viewer::panel_run_controls() {
  const Model& model = *shown_->model;
  ImGui::TextWrapped("%s", shown_->source.c_str());
  ImGui::Text("%d x %d x %d = %lld elements | frame %d", model.dims.x, model.dims.y, model.dims.z,
              static_cast<long long>(model.size()), shown_->frame);
  if (ImGui::Button(running_ ? "Pause (space)" : "Run (space)")) set_running(!running_);
  ImGui::SameLine();
  if (ImGui::Button("Step (n)")) {
    running_ = false;
    runner_->step_frames(1);
  }
  ImGui::SameLine();
  if (ImGui::Button("Reset (r)")) {
    runner_->reset();
    drag_view_ = -1;
  }
  ImGui::SameLine();
  if (ImGui::Button("Shot (s)")) screenshot_request_ = true;
  if (ImGui::SliderFloat("sim rate (fps)", &sim_rate_, 0.0f, 120.0f, sim_rate_ > 0 ? "%.0f" : "as fast as it can",
                         ImGuiSliderFlags_AlwaysClamp))
    runner_->set_rate(sim_rate_);
  ImGui::SliderInt("display limit (fps)", &max_fps_, 0, 240, max_fps_ > 0 ? "%d" : "none", ImGuiSliderFlags_AlwaysClamp);
  ImGui::TextUnformatted(rates_text().c_str());
  const ToolView& t = shown_->tool;
  ImGui::Text("grab: %s", t.held ? "held" : "none");
  if (t.held) {
    ImGui::SameLine();
    ImGui::TextUnformatted(tool_offset_text(t.achieved, model.spacing).c_str());
    if (t.limited)
      ImGui::TextColored(ImVec4(1, 0.6f, 0.15f, 1), "pull limited: asked (%.2f, %.2f, %.2f), %.2f lattice units (%.2f mm) short",
                         double(t.requested.x), double(t.requested.y), double(t.requested.z),
                         double(norm(t.requested - t.achieved)), length_mm(t.requested - t.achieved, model.spacing));
  }
}

void Viewer::panel_backend() {
  if (!cuda_ok_) {
    ImGui::PushStyleColor(ImGuiCol_Text, ImGui::GetStyleColorVec4(ImGuiCol_TextDisabled));
    ImGui::TextWrapped("backend: cpu (CUDA: %s)", cuda_why_.empty() ? "not available" : cuda_why_.c_str());
    ImGui::PopStyleColor();
    return;
  }
  int b = shown_->backend == BackendKind::Cuda ? 1 : 0;
  if (ImGui::Combo("backend", &b, "cpu\0cuda\0")) {
    const BackendKind k = b ? BackendKind::Cuda : BackendKind::Cpu;
    if (k != shown_->backend)
      runner_->replace(std::make_shared<Model>(*shown_->model), edit_, k, shown_->source,
                       std::string("backend: ") + backend_name(k) + " (state reset)");
  }
}

void Viewer::panel_views() {
  if (!ImGui::CollapsingHeader("Views", ImGuiTreeNodeFlags_DefaultOpen)) return;
  int lay = static_cast<int>(layout_);
  if (ImGui::Combo("layout", &lay, "all three\0axial\0coronal\0sagittal\0")) layout_ = static_cast<Layout>(lay);
  int base = static_cast<int>(colour_.base);
  if (ImGui::Combo("colour (t)", &base, "HU window\0tissue class\0")) colour_.base = static_cast<BaseColour>(base);
  if (colour_.base == BaseColour::HuWindow) {
    ImGui::DragFloat("level (HU)", &colour_.level, 2.0f, -1500.0f, 3000.0f, "%.0f");
    ImGui::DragFloat("width (HU)", &colour_.width, 4.0f, 1.0f, 5000.0f, "%.0f", ImGuiSliderFlags_AlwaysClamp);
    if (ImGui::SmallButton("soft tissue")) colour_ = {colour_.base, 40, 400, colour_.overlay, colour_.overlay_max, colour_.overlay_opacity};
    ImGui::SameLine();
    if (ImGui::SmallButton("bone")) colour_ = {colour_.base, 400, 1800, colour_.overlay, colour_.overlay_max, colour_.overlay_opacity};
    ImGui::SameLine();
    if (ImGui::SmallButton("wide")) colour_ = {colour_.base, 0, 2000, colour_.overlay, colour_.overlay_max, colour_.overlay_opacity};
  }
  int ov = static_cast<int>(colour_.overlay);
  if (ImGui::Combo("overlay (o)", &ov, "none\0speed\0|X - X0|\0")) colour_.overlay = static_cast<Overlay>(ov);
  if (colour_.overlay != Overlay::None) {
    ImGui::Checkbox("auto range", &auto_overlay_);
    if (!auto_overlay_)
      ImGui::DragFloat("overlay max", &colour_.overlay_max, 0.01f, 1e-4f, 100.0f, "%.4f", ImGuiSliderFlags_AlwaysClamp | ImGuiSliderFlags_Logarithmic);
    ImGui::SliderFloat("opacity", &colour_.overlay_opacity, 0.0f, 1.0f, "%.2f", ImGuiSliderFlags_AlwaysClamp);
    ImGui::Checkbox("overlay on air", &colour_.overlay_air);
  }
  ImGui::Checkbox("mesh edges (w)", &wire_);
  const Model& model = *shown_->model;
  for (int p = 0; p < kPlaneCount; ++p) {
    View& v = views_[p];
    const char* label[3] = {"axial z", "coronal y", "sagittal x"};
    ImGui::SliderInt(label[p], &v.slice, 0, slice_count(model, v.plane) - 1, "%d", ImGuiSliderFlags_AlwaysClamp);
  }
  if (ImGui::Button("Fit views (f)")) fit_views();
  ImGui::SameLine();
  if (ImGui::Button("Slices to grab point")) default_slices();
  ImGui::TextDisabled("left-drag: grab | right/middle-drag: pan | wheel: zoom");
}

namespace {

void tooltip(const PanelParam& w) {
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("%s", w.tooltip.c_str());
}

ImGuiSliderFlags slider_flags(const PanelParam& w) {
  return ImGuiSliderFlags_AlwaysClamp | (w.logarithmic ? ImGuiSliderFlags_Logarithmic : 0);
}

/// Shortest text of a float (7 significant digits, trailing zeros dropped). ImGui's logarithmic
/// sliders treat values below 10^-precision as 0, so 7 also lets a span from 0 reach 1e-7
/// (dynamics.sleep_speed's default).
constexpr const char* kRealFormat = "%.7g";

bool real_slider(const char* label, float* v, const PanelParam& w) {
  return ImGui::SliderFloat(label, v, float(w.lo), float(w.hi), kRealFormat, slider_flags(w));
}

/// One widget for one parameter of the table: its label gives the valid range, its tooltip
/// the unit and help; sliders run over the table's span.
bool param_widget(const PanelParam& w, Params& p) {
  const ParamSpec& s = *w.spec;
  bool changed = false;
  switch (s.type) {
    case ParamType::Real: changed = real_slider(w.label.c_str(), &s.real(p), w); break;
    case ParamType::Integer:
      if (!s.allowed.empty()) {
        int& v = s.integer(p);
        if (ImGui::BeginCombo(w.label.c_str(), std::to_string(v).c_str())) {
          for (int a : s.allowed)
            if (ImGui::Selectable(std::to_string(a).c_str(), a == v)) v = a, changed = true;
          ImGui::EndCombo();
        }
      } else {
        changed = ImGui::SliderInt(w.label.c_str(), &s.integer(p), int(w.lo), int(w.hi), "%d", slider_flags(w));
      }
      break;
    case ParamType::Flag: changed = ImGui::Checkbox(w.label.c_str(), &s.flag(p)); break;
    case ParamType::Choice: {
      const std::string now = s.choice_name(p);
      if (ImGui::BeginCombo(w.label.c_str(), now.c_str())) {
        for (const std::string& c : s.choices)
          if (ImGui::Selectable(c.c_str(), c == now)) s.set_choice(p, c), changed = true;
        ImGui::EndCombo();
      }
      break;
    }
    case ParamType::PerClass: {
      ImGui::PushID(s.key.c_str());
      ImGui::TextUnformatted((s.name() + " per class, each " + range_text(s)).c_str());
      tooltip(w);
      for (int t = 0; t < kTissueCount; ++t) {
        const std::string l = std::string("  ") + tissue_name(t);
        changed |= real_slider(l.c_str(), &s.per_class(p)[static_cast<std::size_t>(t)], w);
      }
      ImGui::PopID();
      return changed;
    }
    case ParamType::Points:
    case ParamType::PointField: break;  // the control-point rows (panel_tissue_and_material)
  }
  tooltip(w);
  return changed;
}

bool section_widgets(const char* section, Params& p) {
  bool changed = false;
  for (const PanelParam& w : panel_params(section)) changed |= param_widget(w, p);
  return changed;
}

}  // namespace

bool Viewer::panel_solver_and_dynamics() {
  bool changed = false;
  ImGui::PushItemWidth(-190);  // room for the labels with their ranges
  if (ImGui::CollapsingHeader("Grab tool and solver", ImGuiTreeNodeFlags_DefaultOpen)) changed |= section_widgets("solver", edit_);
  if (ImGui::CollapsingHeader("Dynamics (velocity layer)", ImGuiTreeNodeFlags_DefaultOpen)) {
    ImGui::TextDisabled("mode: 1/2/3 = none/simple/viscoelastic");
    changed |= section_widgets("dynamics", edit_);
    const PerTissue s = edit_.dynamics.response_scale();
    ImGui::TextDisabled("response scale s: %.3f %.3f %.3f %.3f", double(s[0]), double(s[1]), double(s[2]), double(s[3]));
  }
  ImGui::PopItemWidth();
  return changed;
}

bool Viewer::panel_tissue_and_material() {
  if (!ImGui::CollapsingHeader("Tissue classes and material")) return false;
  bool changed = false;
  ImGui::TextDisabled("t1 < t2 < t3 (HU); rebuilds the materials");
  for (const PanelParam& w : panel_params("tissue")) {
    changed |= ImGui::DragFloat(w.label.c_str(), &w.spec->real(edit_), 1.0f, float(w.lo), float(w.hi), "%.0f");
    tooltip(w);
  }
  TissueThresholds& t = edit_.tissue;
  if (ImGui::SmallButton("paper thresholds")) {
    t = TissueThresholds{};
    changed = true;
  }
  ImGui::SameLine();
  if (ImGui::SmallButton("robust preset")) {
    t = TissueThresholds::robust_preset();
    changed = true;
  }
  std::vector<PanelParam> columns;
  std::string points_help, column_ranges;
  for (const PanelParam& w : panel_params("material"))
    if (w.spec->type == ParamType::PointField) {
      column_ranges += (columns.empty() ? "" : ", ") + w.label;
      columns.push_back(w);
    } else {
      points_help = w.spec->help;
    }
  ImGui::TextWrapped("%s. Ranges: %s", points_help.c_str(), column_ranges.c_str());
  auto& pts = edit_.material.points;
  int remove = -1;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    ImGui::PushID(static_cast<int>(i));
    ImGui::PushItemWidth(70);
    for (std::size_t c = 0; c < columns.size(); ++c) {
      const PanelParam& w = columns[c];
      const std::string id = "##" + w.spec->name(), format = w.spec->name() + " " + kRealFormat;
      if (c) ImGui::SameLine();
      const float speed = w.logarithmic ? 0.001f : 1.0f;
      changed |= ImGui::DragFloat(id.c_str(), &(pts[i].*(w.spec->point_field)), speed, float(w.lo), float(w.hi),
                                  format.c_str(), slider_flags(w));
      tooltip(w);
    }
    ImGui::PopItemWidth();
    ImGui::SameLine();
    if (pts.size() > 2 && ImGui::SmallButton("x")) remove = static_cast<int>(i);
    ImGui::PopID();
  }
  if (remove >= 0) {
    pts.erase(pts.begin() + remove);
    changed = true;
  }
  if (ImGui::SmallButton("add point")) {
    MaterialPoint q = pts.back();
    q.hu += 100;
    pts.push_back(q);
    changed = true;
  }
  ImGui::SameLine();
  if (ImGui::SmallButton("default material")) {
    edit_.material = MaterialTable{};
    changed = true;
  }
  const Model& model = *shown_->model;
  ImGui::Text("elements: air %lld, skin&fat %lld, muscle %lld, bone %lld", static_cast<long long>(model.class_count[0]),
              static_cast<long long>(model.class_count[1]), static_cast<long long>(model.class_count[2]),
              static_cast<long long>(model.class_count[3]));
  return changed;
}

void Viewer::panel_parameter_file() {
  if (!ImGui::CollapsingHeader("Parameter file")) return;
  ImGui::InputText("path##params", params_path_, sizeof params_path_);
#ifdef HPCM_VIEWER_WITH_CONFIG
  if (ImGui::Button("Save")) {
    try {
      const std::string text = config::params_to_toml(shown_->params);  // the parameters in use
      const std::string tmp = std::string(params_path_) + ".tmp";
      {
        std::ofstream f(tmp, std::ios::binary);
        f << text;
        f.close();
        if (!f) throw Error(std::string("cannot write ") + params_path_ + " (disk full?)");
      }
      std::filesystem::rename(tmp, params_path_);
      message(std::string("saved ") + params_path_);
    } catch (const std::exception& e) {
      message(e.what(), true);
    }
  }
  ImGui::SameLine();
  if (ImGui::Button("Load")) {
    try {
      edit_ = config::load_params(params_path_);
      apply_params(true);
      if (param_error_.empty()) message(std::string("loaded ") + params_path_);
    } catch (const Error& e) {
      message(e.what(), true);
    }
  }
  ImGui::SameLine();
#else
  ImGui::TextDisabled("parameter files need hpcm built with toml++ (hpcm::config)");
#endif
  if (ImGui::Button("Defaults")) {
    edit_ = Params{};
    apply_params(true);
  }
}

void Viewer::panel_scenario() {
  if (!ImGui::CollapsingHeader("Scenario")) return;
  const ScenarioView& sc = shown_->scenario;
  if (sc.loaded)
    ImGui::Text("%s: %d frames, %zu grab(s); %s, frame %d", sc.name.c_str(), sc.frames, sc.grabs,
                sc.playing ? (sc.done ? "done" : "playing") : "stopped", sc.player_frame);
  else
    ImGui::TextDisabled("no scenario");
  ImGui::InputText("file##scenario", scenario_path_, sizeof scenario_path_);
  // The simulation thread validates the scenario against the lattice; an error comes back as a
  // message and the old scenario stays.
  auto use = [&](std::optional<Scenario> s) {
    runner_->set_scenario(std::move(s));
    running_ = true;
    drag_view_ = -1;
    slices_to_new_scenario_ = true;
  };
#ifdef HPCM_VIEWER_WITH_CONFIG
  if (ImGui::Button("Load + play")) {
    try {
      use(config::load_scenario(scenario_path_));
    } catch (const Error& e) {
      message(e.what(), true);
    }
  }
  ImGui::SameLine();
#endif
  if (ImGui::Button("Paper protocol")) use(Scenario::paper_protocol());
  ImGui::SameLine();
  if (ImGui::Button("Replay")) {
    runner_->reset();
    set_running(true);
  }
  ImGui::SameLine();
  if (ImGui::Button("None")) use(std::nullopt);
}

void Viewer::panel_data() {
  if (!ImGui::CollapsingHeader("Data")) return;
  // Reading and building the model happen here (the display pauses while a volume loads);
  // the new simulation is made on the simulation thread.
#ifdef HPCM_VIEWER_WITH_IO
  ImGui::InputText("volume", volume_path_, sizeof volume_path_);
  ImGui::SliderInt("down-sample", &load_downsample_, 1, 8, "%d", ImGuiSliderFlags_AlwaysClamp);
  if (ImGui::Button("Load volume")) {
    try {
      Volume v = io::read_volume(volume_path_);
      if (load_downsample_ > 1) v = downsample(v, load_downsample_);
      auto m = std::make_shared<Model>(build_model(v, shown_->params));
      const std::string src = std::string(volume_path_) + (load_downsample_ > 1 ? " (f=" + std::to_string(load_downsample_) + ")" : "");
      runner_->replace(std::move(m), shown_->params, shown_->backend, src, "loaded " + src);
    } catch (const Error& e) {
      message(e.what(), true);
    }
  }
#else
  ImGui::TextDisabled("volume files need hpcm built with ITK (hpcm::io)");
#endif
  ImGui::InputInt3("phantom NX,NY,NZ", phantom_dims_);
  ImGui::InputInt("seed", &phantom_seed_);
  ImGui::SliderFloat("noise (HU) [0,200]", &phantom_noise_, 0, 200, "%.1f", ImGuiSliderFlags_AlwaysClamp);
  if (ImGui::Button("Generate phantom")) {
    try {
      PhantomOptions po;
      po.dims = {phantom_dims_[0], phantom_dims_[1], phantom_dims_[2]};
      po.seed = static_cast<std::uint64_t>(std::max(phantom_seed_, 0));
      po.noise_hu = phantom_noise_;
      auto m = std::make_shared<Model>(build_model(make_phantom(po), shown_->params));
      char src[96];
      std::snprintf(src, sizeof src, "phantom %dx%dx%d (seed %d)", po.dims.x, po.dims.y, po.dims.z, phantom_seed_);
      runner_->replace(std::move(m), shown_->params, shown_->backend, src, std::string("generated ") + src);
    } catch (const Error& e) {
      message(e.what(), true);
    }
  }
}

}  // namespace hpcm::viewer
