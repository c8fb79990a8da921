// The viewer's simulation thread (apps/viewer/sim_runner.hpp): commands reach the simulation
// between frames and give the same frames as calling the Simulation directly; the display
// side never waits for a frame in progress; a limited pull is announced once per grab; in
// lock-step every frame is taken. No timing is asserted: waits have generous deadlines only
// so that a broken build fails instead of hanging.
#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <thread>

#include "sim_runner.hpp"

using namespace hpcm;
using namespace hpcm::viewer;

namespace {

Model phantom_model(Int3 dims, const Params& p) {
  PhantomOptions po;
  po.dims = dims;
  return build_model(make_phantom(po), p);
}

/// Polls the latest frame until `done` holds; fails the test after 120 s.
std::shared_ptr<const PublishedFrame> wait_until(SimRunner& r,
                                                 const std::function<bool(const PublishedFrame&)>& done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  for (;;) {
    auto f = r.latest();
    if (f && done(*f)) return f;
    if (std::chrono::steady_clock::now() > deadline) {
      ADD_FAILURE() << "the simulation thread did not get there (last frame " << (f ? f->frame : -1) << ")";
      return f;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

std::shared_ptr<const PublishedFrame> wait_frame(SimRunner& r, int frame) {
  return wait_until(r, [&](const PublishedFrame& f) { return f.frame >= frame; });
}

int count(const std::vector<Notice>& ns, Notice::Kind k) {
  int n = 0;
  for (const Notice& x : ns) n += x.kind == k;
  return n;
}

}  // namespace

TEST(ViewerSimRunner, CommandsGiveTheSameFramesAsTheSimulationItself) {
  const Params p;
  const Int3 dims{24, 24, 16};
  Simulation direct(phantom_model(dims, p), p);
  const Index centre = paper_grab_centre(direct.model());
  SimRunner runner(std::make_unique<Simulation>(phantom_model(dims, p), p), std::nullopt, "phantom");
  runner.start(false);

  runner.grab(centre, 0);
  runner.move_tool({0, -1.0f, 0});
  runner.move_tool({0, -2.0f, 0.5f});  // collapses with the move before: only the last offset counts
  runner.step_frames(3);
  wait_frame(runner, 3);
  runner.move_tool({0, -3.0f, 0});
  runner.step_frames(2);
  wait_frame(runner, 5);
  runner.release();
  runner.step_frames(3);
  const auto f = wait_frame(runner, 8);

  direct.grab(centre, 0);
  direct.move_tool({0, -2.0f, 0.5f});
  for (int k = 0; k < 3; ++k) direct.step();
  direct.move_tool({0, -3.0f, 0});
  for (int k = 0; k < 2; ++k) direct.step();
  direct.release();
  for (int k = 0; k < 2; ++k) direct.step();
  // The views get the displacements u = X - X0.
  auto displacements = [&] { return direct.state().disp; };
  const std::vector<Vec3> before_last = displacements();
  direct.step();

  ASSERT_TRUE(f && f->disp && f->prev);
  EXPECT_EQ(f->frame, 8);
  EXPECT_TRUE(f->stepped);
  EXPECT_FALSE(f->tool.held);
  EXPECT_TRUE(f->tool.shown);
  EXPECT_EQ(f->tool.centre, centre);
  EXPECT_EQ(*f->disp, displacements());  // bitwise: the thread changes nothing in the physics
  EXPECT_EQ(*f->prev, before_last);        // u(t-1) for the speed overlay
  std::size_t moved = 0;
  for (std::size_t i = 0; i < before_last.size(); ++i) moved += !(before_last[i] == Vec3{});
  EXPECT_GT(moved, 0u) << "the grab moved nothing: the comparison would be empty";
  const auto samples = runner.take_samples();
  ASSERT_EQ(samples.size(), 8u);  // one per frame, none skipped
  EXPECT_EQ(samples.back().frame, 8);
}

// The display's buffers are taken again and brought up to date from the bricks written since
// (Backend::download_displacements_since). New data start a new backend: its stamps continue
// the process-wide sequence, so every buffer is filled anew (fails when a reused buffer keeps
// the old lattice's positions, as it did with stamps counted per backend).
TEST(ViewerSimRunner, NewDataFillTheReusedBuffersAnew) {
  const Params p;
  const Int3 dims{24, 24, 16};
  const Model first = phantom_model(dims, p);
  const Index centre = paper_grab_centre(first);
  SimRunner runner(std::make_unique<Simulation>(first, p), std::nullopt, "phantom");
  runner.start(false);
  runner.grab(centre, 0);
  runner.move_tool({0, -2.0f, 0});
  runner.step_frames(12);  // frames with many moved bricks, several buffers in turn
  wait_frame(runner, 12);
  PhantomOptions po;
  po.dims = dims;
  po.seed = 2;  // another noise: other tissue, other motion
  const Model second = build_model(make_phantom(po), p);
  runner.replace(std::make_shared<Model>(second), p, BackendKind::Cpu, "phantom, seed 2", "");
  wait_until(runner, [](const PublishedFrame& f) { return f.source == "phantom, seed 2"; });
  runner.grab(centre, 0);
  runner.move_tool({0, -1.0f, 0});
  runner.step_frames(3);
  const auto f = wait_until(runner, [](const PublishedFrame& g) { return g.source == "phantom, seed 2" && g.frame >= 3; });
  Simulation direct(second, p);
  direct.grab(centre, 0);
  direct.move_tool({0, -1.0f, 0});
  for (int k = 0; k < 3; ++k) direct.step();
  ASSERT_TRUE(f && f->disp);
  EXPECT_EQ(f->frame, 3);
  EXPECT_EQ(*f->disp, direct.state().disp);
}

TEST(ViewerSimRunner, TheDisplayGoesOnWhileASimulationFrameIsHeld) {
  const Params p;
  SimRunner runner(std::make_unique<Simulation>(phantom_model({24, 24, 16}, p), p), Scenario::paper_protocol(), "phantom");
  // Frame 3 is held on the simulation thread until the display side has drawn 50 frames,
  // like a slow frame; a display that waited for it would never get there.
  long drawn_meanwhile = -1;
  runner.set_before_step([&](int k) {
    if (k == 3) drawn_meanwhile = runner.wait_for_display_frames(50, 120.0);
  });
  runner.start(true);
  wait_frame(runner, 2);
  int shown_while_held = 0;
  long draws = 0;
  while (runner.latest()->frame < 3) {
    const auto f = runner.latest();  // returns at once: the frame in progress is not waited for
    shown_while_held += f->frame == 2;
    runner.note_display_frame();
    ++draws;
    ASSERT_LT(draws, 100000000L) << "frame 3 never came";
  }
  const auto f = wait_frame(runner, 6);
  runner.stop();
  EXPECT_GE(drawn_meanwhile, 50) << "the simulation frame was released by the deadline, not by the display";
  EXPECT_GE(shown_while_held, 50);
  EXPECT_EQ(runner.display_frames(), draws);
  EXPECT_GE(f->frame, 6);
}

TEST(ViewerSimRunner, ALimitedPullIsAnnouncedOncePerGrabWithItsLargestShortfall) {
  const Params p;
  SimRunner runner(std::make_unique<Simulation>(phantom_model({32, 32, 20}, p), p), std::nullopt, "phantom");
  runner.start(false);
  const Index centre = runner.latest()->reference_centre;
  ASSERT_GE(centre, 0);

  // A pull the tissue can follow: nothing to say, also at release.
  runner.grab(centre, 0);
  runner.move_tool({0, -1.0f, 0});
  runner.step_frames(3);
  auto f = wait_frame(runner, 3);
  EXPECT_FALSE(f->tool.limited);
  runner.release();
  runner.step_frames(1);
  wait_frame(runner, 4);
  EXPECT_EQ(count(runner.take_notices(), Notice::Kind::PullLimited), 0);

  // 40, then 50 cells anterior: beyond the lattice border, so the tissue cannot follow. The
  // frames show it live; the message comes once, when the grab ends, with the worst figures.
  runner.grab(centre, 0);
  runner.move_tool({0, -40.0f, 0});
  runner.step_frames(3);
  f = wait_frame(runner, 7);
  ASSERT_TRUE(f->tool.held);
  ASSERT_TRUE(f->tool.limited);
  EXPECT_EQ(f->tool.requested.y, -40.0f);
  EXPECT_GT(f->tool.achieved.y, -40.0f);
  EXPECT_LT(norm(f->tool.achieved), norm(f->tool.requested));
  runner.move_tool({0, -50.0f, 0});
  runner.step_frames(2);
  f = wait_frame(runner, 9);
  EXPECT_TRUE(f->tool.limited);
  EXPECT_EQ(count(runner.take_notices(), Notice::Kind::PullLimited), 0);
  runner.move_tool({0, -45.0f, 0});  // a smaller shortfall before the release
  runner.release();
  runner.step_frames(2);
  wait_frame(runner, 11);
  auto notices = runner.take_notices();
  ASSERT_EQ(count(notices, Notice::Kind::PullLimited), 1);
  std::string text;
  for (const Notice& n : notices)
    if (n.kind == Notice::Kind::PullLimited) text = n.text;
  const Vec3 worst_requested{0, -50.0f, 0};
  EXPECT_NE(text.find(limited_pull_text(f->tool.achieved, worst_requested, f->model->spacing)), std::string::npos)
      << text;

  // A new grab pulled too far is announced again, here on request (the end of a scripted run).
  runner.grab(centre, 0);
  runner.move_tool({0, -30.0f, 0});
  runner.step_frames(1);
  wait_frame(runner, 12);
  EXPECT_EQ(count(runner.take_notices(), Notice::Kind::PullLimited), 0);
  const std::uint64_t seq = runner.latest_seq();
  runner.announce_pending();
  wait_until(runner, [&](const PublishedFrame& x) { return x.seq > seq; });
  EXPECT_EQ(count(runner.take_notices(), Notice::Kind::PullLimited), 1);
  runner.announce_pending();
  runner.release();
  runner.step_frames(1);
  wait_frame(runner, 13);
  EXPECT_EQ(count(runner.take_notices(), Notice::Kind::PullLimited), 0);  // said once
}

TEST(ViewerSimRunner, PositionsAreDownloadedAgainOnlyWhenTheyChanged) {
  const Params p;
  SimRunner runner(std::make_unique<Simulation>(phantom_model({20, 20, 12}, p), p), std::nullopt, "phantom");
  runner.start(false);
  const auto rest = runner.latest();
  const Index centre = rest->reference_centre;
  ASSERT_GE(centre, 0);

  // Grab and tool moves while paused: new frames are published (the tool moved), the
  // positions are the same buffer with the same id (nothing for the display to re-upload).
  runner.grab(centre, 0);
  runner.move_tool({0, -2.0f, 0});
  auto f = wait_until(runner, [](const PublishedFrame& x) { return x.tool.requested.y == -2.0f; });
  EXPECT_GT(f->seq, rest->seq);
  EXPECT_EQ(f->positions_id, rest->positions_id);
  EXPECT_EQ(f->disp.get(), rest->disp.get());

  // A frame moves the tissue: a new download, a new id, and the old positions become X(t-1).
  runner.step_frames(1);
  const auto stepped = wait_frame(runner, 1);
  EXPECT_NE(stepped->positions_id, rest->positions_id);
  EXPECT_NE(stepped->disp.get(), rest->disp.get());
  EXPECT_EQ(stepped->prev.get(), rest->disp.get());
  EXPECT_NE(*stepped->disp, *rest->disp);

  // A parameter change may reload the backend: downloaded again (same values), X(t-1) kept.
  Params q = p;
  q.dynamics.mode = DampingMode::Simple;
  runner.set_params(q);
  f = wait_until(runner, [](const PublishedFrame& x) { return x.params.dynamics.mode == DampingMode::Simple; });
  EXPECT_NE(f->positions_id, stepped->positions_id);
  EXPECT_EQ(*f->disp, *stepped->disp);
  EXPECT_EQ(f->prev.get(), stepped->prev.get());
}

TEST(ViewerSimRunner, LockStepHandsOverEveryFrame) {
  const Params p;
  SimRunner runner(std::make_unique<Simulation>(phantom_model({20, 20, 12}, p), p), Scenario::paper_protocol(), "phantom");
  runner.set_lockstep(true);
  runner.run_to_frame(12);
  runner.start(false);
  std::vector<int> seen;
  std::uint64_t last_seq = 0;
  for (long spins = 0; seen.size() < 12 && spins < 100000000L; ++spins) {
    const auto f = runner.latest();
    if (f->seq != last_seq && f->stepped) seen.push_back(f->frame);
    last_seq = f->seq;
  }
  ASSERT_EQ(seen.size(), 12u);
  for (int k = 0; k < 12; ++k) EXPECT_EQ(seen[static_cast<std::size_t>(k)], k + 1);
}

TEST(ViewerSimRunner, ResetAndParametersApplyBetweenFrames) {
  const Params p;
  SimRunner runner(std::make_unique<Simulation>(phantom_model({20, 20, 12}, p), p), Scenario::paper_protocol(), "phantom");
  runner.start(false);
  runner.step_frames(4);
  const auto before = wait_frame(runner, 4);
  EXPECT_TRUE(before->tool.held);  // the paper protocol grabbed

  Params q = p;
  q.dynamics.mode = DampingMode::Simple;
  runner.set_params(q);
  auto f = wait_until(runner, [](const PublishedFrame& x) { return x.params.dynamics.mode == DampingMode::Simple; });
  EXPECT_EQ(f->frame, 4);  // a parameter change is not a frame

  Params bad = q;
  bad.dynamics.s_min = 0.9f;
  bad.dynamics.s_max = 0.1f;
  runner.set_params(bad);
  runner.reset();
  f = wait_until(runner, [&](const PublishedFrame& x) { return x.epoch != before->epoch; });
  EXPECT_EQ(f->frame, 0);
  EXPECT_FALSE(f->prev);  // no previous frame: speed 0
  EXPECT_FALSE(f->tool.shown);
  EXPECT_EQ(f->params.dynamics.mode, DampingMode::Simple);  // the invalid set was not applied
  const auto notices = runner.take_notices();
  EXPECT_EQ(count(notices, Notice::Kind::ParamError), 1);
  for (std::size_t i = 0; i < f->disp->size(); ++i)
    ASSERT_TRUE((*f->disp)[i] == Vec3{}) << "element " << i << " not at rest after reset";
}

TEST(ViewerRateMeter, CountsFramesOverItsWindow) {
  RateMeter m(1.0);
  EXPECT_EQ(m.rate(), 0.0);
  for (int k = 0; k <= 30; ++k) m.add(k / 30.0, k);  // 30 frames per second for one second
  EXPECT_NEAR(m.rate(), 30.0, 1e-9);
  for (int k = 1; k <= 20; ++k) m.add(1.0 + k / 10.0, 30 + k);  // then 10 per second for two seconds
  EXPECT_NEAR(m.rate(), 10.0, 1e-9);
}

TEST(ViewerSimRunner, ToolOffsetTextGivesThePullInLatticeUnitsAndMillimetres) {
  const std::string t = tool_offset_text({3.0f, -4.0f, 0}, {0.5, 2.0, 1.0});
  EXPECT_EQ(t, "offset (3.00, -4.00, 0.00) = 5.00 lattice units (8.14 mm)");
}

TEST(ViewerSimRunner, LimitedPullTextNamesBothOffsetsInLatticeUnitsAndMillimetres) {
  const std::string t = limited_pull_text({0, -3.0f, 0}, {0, -8.0f, 0}, {0.5, 2.0, 1.0});
  EXPECT_NE(t.find("pull limited"), std::string::npos) << t;
  EXPECT_NE(t.find("3.00 of the requested 8.00 lattice units"), std::string::npos) << t;
  EXPECT_NE(t.find("(6.00 of 16.00 mm), 5.00 lattice units (10.00 mm) short"), std::string::npos) << t;
  EXPECT_NE(t.find("achieved offset (0.00, -3.00, 0.00), requested (0.00, -8.00, 0.00)"), std::string::npos) << t;
}
