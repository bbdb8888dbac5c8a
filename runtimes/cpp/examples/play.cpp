// segadeform-play: a program of one's own on the C++ library (include/segadeform/player.hpp, the CMake target
// `segadeform`), and the library's test driver.  It plays a motion file as if it arrived live, `--chunk` frames at a
// time, and writes the garment's frames as a PC2 point cache under the output rule of segadeform-run and `segadeform
// run` (src/outputs.hpp, the command lines' and not the library's): a new path, or a file an earlier run wrote (the
// folder's .segadeform-outputs.json records it), is written; a file segadeform did not write, or an input, is refused.
//
//   segadeform-play PACKAGE G.sgda M.sgdm -o OUT.pc2 [--chunk N] [--batch N] [--effects E] [--cloth K=V,..]
//                   [--collision-margin M (or --margin M)] [--threads N] [--force]
#include <segadeform/player.hpp>

#include "outputs.hpp"  // the command lines' output rule and manifest (segadeform-run's)

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

static const char* USAGE =
    "usage: segadeform-play PACKAGE G.sgda M.sgdm -o OUT.pc2 [--chunk N] [--batch N] [--effects E] [--cloth K=V,..]\n"
    "                       [--collision-margin M] [--threads N] [--force]\n";

// The whole of t as a number (std::stoi/stod read "8x" as 8 and "abc" said only "stoi": a user's trial).
static long long whole_int(const std::string& name, const std::string& t) {
  size_t end = 0;
  long long v = 0;
  try {
    v = std::stoll(t, &end);
  } catch (const std::exception&) {
    end = 0;
  }
  if (end == 0 || end != t.size()) throw std::invalid_argument(name + " must be an integer (got '" + t + "')");
  return v;
}

// An int-sized whole_int (4294967297 would wrap to 1).
static int small_int(const std::string& name, const std::string& t) {
  const long long v = whole_int(name, t);
  if (v < -2147483647LL || v > 2147483647LL) throw std::invalid_argument(name + " is out of range (got '" + t + "')");
  return static_cast<int>(v);
}

static double whole_number(const std::string& name, const std::string& t) {
  size_t end = 0;
  double v = 0;
  try {
    v = std::stod(t, &end);
  } catch (const std::exception&) {
    end = 0;
  }
  if (end == 0 || end != t.size()) throw std::invalid_argument(name + " must be a number (got '" + t + "')");
  return v;
}

int main(int argc, char** argv) {
  std::vector<std::string> pos;
  std::string out;
  int64_t chunk = 1;
  segadeform::PlayerOptions opt;
  try {
    const std::vector<std::string> args = sgd::command_args(argc, argv);  // --effects=+cloth as the docs write it
    for (size_t i = 0; i < args.size(); ++i) {
      const std::string& a = args[i];
      const bool more = i + 1 < args.size();
      if (a == "--help" || a == "-h") {
        std::cout << USAGE;
        return 0;
      }
      if (a == "-o" && more) out = args[++i];
      else if (a == "--chunk" && more) chunk = whole_int(a, args[++i]);
      else if (a == "--batch" && more) opt.batch = small_int(a, args[++i]);
      else if (a == "--threads" && more) opt.threads = small_int(a, args[++i]);
      else if (a == "--effects" && more) opt.effects = args[++i];
      else if (a == "--cloth" && more) opt.cloth = args[++i];
      else if ((a == "--margin" || a == "--collision-margin") && more)
        opt.collision_margin = whole_number(a, args[++i]);
      else if (a == "--force") opt.force = true;
      else if (a.size() > 1 && a[0] == '-') throw std::invalid_argument("unknown option or missing value: " + a);
      else pos.push_back(a);
    }
    if (pos.size() != 3 || out.empty() || chunk < 1)
      throw std::invalid_argument("expected PACKAGE G.sgda M.sgdm -o OUT.pc2 and --chunk N >= 1");
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n" << USAGE;
    return 2;
  }
  // the output is claimed before any work, as segadeform-run claims it
  const std::vector<std::string> outputs{out}, inputs{pos[0], pos[1], pos[2]};
  try {
    sgd::claim_outputs(outputs, inputs);
  } catch (const std::exception& e) {
    std::cerr << "Error: " << sgd::outputs_detail::one_line(e.what()) << "\n";
    return 1;
  }
  try {
    const segadeform::Motion m = segadeform::read_motion(pos[2], pos[1], opt.force);
    opt.fps = m.fps;
    segadeform::Player player(pos[0], pos[1], opt);
    for (const auto& w : m.warnings) std::cerr << "warning: " << w << "\n";
    for (const auto& w : player.warnings()) std::cerr << "warning: " << w << "\n";
    const int64_t N = player.vertices(), D = 3 * player.joints();
    // written as the frames arrive (a stream holds one chunk, not the clip: 10,002 frames held 468 MB), to a
    // temporary file that the commit below puts in place (removed if anything fails first)
    const std::string tmp = sgd::temporary(out);
    try {
      std::ofstream f(tmp, std::ios::binary);
      const int32_t version = 1, n = static_cast<int32_t>(N), t = static_cast<int32_t>(m.frames);
      const float start = static_cast<float>(m.start_frame), rate = 1.f;  // numbered as segadeform-run numbers it
      f.write("POINTCACHE2\0", 12);
      f.write(reinterpret_cast<const char*>(&version), 4);
      f.write(reinterpret_cast<const char*>(&n), 4);
      f.write(reinterpret_cast<const char*>(&start), 4);
      f.write(reinterpret_cast<const char*>(&rate), 4);
      f.write(reinterpret_cast<const char*>(&t), 4);
      for (int64_t lo = 0; lo < m.frames && f; lo += chunk) {  // as the frames arrive
        const int64_t B = std::min<int64_t>(chunk, m.frames - lo);
        const std::vector<float> got = player.push(m.poses.data() + lo * D, m.trans.data() + lo * 3, B);
        f.write(reinterpret_cast<const char*>(got.data()), static_cast<std::streamsize>(got.size() * sizeof(float)));
      }
      f.close();
      if (!f) throw std::runtime_error(out + ": write failed");
    } catch (...) {
      std::remove(tmp.c_str());
      throw;
    }
    sgd::commit_outputs(outputs, inputs);  // into place, and recorded in the folder's manifest
    const segadeform::Counts c = player.counts();
    const std::string effects = player.effects();  // "lbs,dynamics,wrinkles,cloth": cloth in collisions' place
    const auto on = [&](const std::string& name) {
      return ("," + effects + ",").find("," + name + ",") != std::string::npos;
    };
    std::printf("%lld frames in chunks of %lld (%s) -> %s", static_cast<long long>(c.frames),
                static_cast<long long>(chunk), effects.c_str(), out.c_str());
    if (on("cloth"))  // the stage's counts only when it runs, as segadeform-run and `segadeform run` print them
      std::printf("; cloth: %lld in contact, %lld reset(s)", static_cast<long long>(c.contacts),
                  static_cast<long long>(c.resets));
    else if (on("collisions"))
      std::printf("; collisions moved %lld", static_cast<long long>(c.moved));
    std::printf("\n");
  } catch (const std::exception& e) {
    std::remove(sgd::temporary_name(out).c_str());  // a failed run leaves no output
    std::cerr << "Error: " << sgd::outputs_detail::one_line(e.what()) << "\n";
    return 1;
  }
  return 0;
}
