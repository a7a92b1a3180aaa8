#include "motion/bvh.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "core/error.hpp"
#include "core/fileio.hpp"

namespace ks {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Line {
  int no = 0;
  std::vector<std::string> tok;
};

std::vector<Line> split_lines(const std::string& text) {
  std::vector<Line> out;
  std::istringstream in(text);
  std::string s;
  int no = 0;
  while (std::getline(in, s)) {
    ++no;
    Line l;
    l.no = no;
    std::istringstream ls(s);
    std::string t;
    while (ls >> t) l.tok.push_back(t);
    if (!l.tok.empty()) out.push_back(std::move(l));
  }
  return out;
}

class Parser {
 public:
  Parser(const std::string& text, const std::string& what)
      : lines_(split_lines(text)), what_(what) {}

  Bvh parse() {
    Bvh b;
    if (lines_.empty() || lines_[0].tok[0] != "HIERARCHY")
      throw Error(what_ + ": not a BVH file (no HIERARCHY at the start)");
    i_ = 1;
    if (i_ >= lines_.size() || lines_[i_].tok[0] != "ROOT") fail("expected ROOT");
    int channel = 0;
    joint(b, -1, channel);
    if (i_ < lines_.size() && lines_[i_].tok[0] == "ROOT")
      fail("a second ROOT (only one skeleton per file is read)");
    if (i_ >= lines_.size() || lines_[i_].tok[0] != "MOTION") fail("expected MOTION");
    ++i_;
    // Frames: N
    if (i_ >= lines_.size() || lines_[i_].tok.size() != 2 || lines_[i_].tok[0] != "Frames:")
      fail("expected \"Frames: N\"");
    const double nf = number(lines_[i_].tok[1]);
    if (nf < 0 || nf != std::floor(nf) || nf > 1e7) fail("bad frame count");
    ++i_;
    if (i_ >= lines_.size() || lines_[i_].tok.size() != 3 || lines_[i_].tok[0] != "Frame" ||
        lines_[i_].tok[1] != "Time:")
      fail("expected \"Frame Time: SECONDS\"");
    b.frame_time = number(lines_[i_].tok[2]);
    if (!(b.frame_time > 0)) fail("Frame Time must be positive");
    ++i_;
    const int F = int(nf), C = channel;
    b.frames.resize(F, C);
    for (int f = 0; f < F; ++f, ++i_) {
      if (i_ >= lines_.size())
        throw Error(what_ + ": " + std::to_string(f) + " frame lines, \"Frames:\" says " +
                    std::to_string(F) + " (truncated?)");
      const Line& l = lines_[i_];
      if (int(l.tok.size()) != C)
        fail("frame " + std::to_string(f) + " has " + std::to_string(l.tok.size()) +
             " values, the hierarchy has " + std::to_string(C) + " channels");
      for (int c = 0; c < C; ++c) b.frames(f, c) = number(l.tok[size_t(c)]);
    }
    return b;
  }

 private:
  [[noreturn]] void fail(const std::string& msg) const {
    const int no = i_ < lines_.size() ? lines_[i_].no : (lines_.empty() ? 0 : lines_.back().no);
    throw Error(what_ + ":" + std::to_string(no) + ": " + msg);
  }

  double number(const std::string& s) const {
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v))
      fail("\"" + s + "\" is not a finite number");
    return v;
  }

  void expect_open() {
    if (i_ >= lines_.size() || lines_[i_].tok.size() != 1 || lines_[i_].tok[0] != "{")
      fail("expected \"{\"");
    ++i_;
  }

  Eigen::Vector3d offset() {
    const Line& l = lines_[i_];
    if (l.tok.size() != 4) fail("OFFSET needs 3 numbers");
    Eigen::Vector3d o(number(l.tok[1]), number(l.tok[2]), number(l.tok[3]));
    ++i_;
    return o;
  }

  void joint(Bvh& b, int parent, int& channel) {
    const Line& head = lines_[i_];
    if (head.tok.size() < 2) fail(head.tok[0] + " without a name");
    BvhJoint j;
    for (size_t k = 1; k < head.tok.size(); ++k) {
      if (k > 1) j.name += ' ';
      j.name += head.tok[k];
    }
    j.parent = parent;
    ++i_;
    expect_open();
    const int index = int(b.joints.size());
    b.joints.push_back(j);
    if (b.joints.size() > 100000) fail("too many joints");
    bool have_offset = false, have_channels = false;
    while (true) {
      if (i_ >= lines_.size())
        fail("unbalanced braces (end of file inside joint \"" + j.name + "\")");
      const Line& l = lines_[i_];
      const std::string& k = l.tok[0];
      if (k == "}") {
        ++i_;
        break;
      }
      if (k == "OFFSET") {
        if (have_offset) fail("a second OFFSET in joint \"" + j.name + "\"");
        b.joints[size_t(index)].offset = offset();
        have_offset = true;
      } else if (k == "CHANNELS") {
        if (have_channels) fail("a second CHANNELS in joint \"" + j.name + "\"");
        if (l.tok.size() < 2) fail("CHANNELS without a count");
        const double n = number(l.tok[1]);
        if (n < 0 || n > 6 || n != std::floor(n) || size_t(n) + 2 != l.tok.size())
          fail("CHANNELS count does not match the channels listed");
        BvhJoint& bj = b.joints[size_t(index)];
        bj.first_channel = channel;
        for (size_t c = 2; c < l.tok.size(); ++c) {
          const std::string& t = l.tok[c];
          if (t == "Xposition")
            bj.channels.push_back(BvhChannel::kXpos);
          else if (t == "Yposition")
            bj.channels.push_back(BvhChannel::kYpos);
          else if (t == "Zposition")
            bj.channels.push_back(BvhChannel::kZpos);
          else if (t == "Xrotation")
            bj.channels.push_back(BvhChannel::kXrot);
          else if (t == "Yrotation")
            bj.channels.push_back(BvhChannel::kYrot);
          else if (t == "Zrotation")
            bj.channels.push_back(BvhChannel::kZrot);
          else
            fail("unknown channel \"" + t + "\"");
        }
        channel += int(bj.channels.size());
        have_channels = true;
        ++i_;
      } else if (k == "JOINT") {
        joint(b, index, channel);
      } else if (k == "End") {
        if (l.tok.size() != 2 || l.tok[1] != "Site") fail("expected \"End Site\"");
        ++i_;
        expect_open();
        if (i_ >= lines_.size() || lines_[i_].tok[0] != "OFFSET") fail("End Site without OFFSET");
        b.joints[size_t(index)].end_site = offset();
        b.joints[size_t(index)].has_end_site = true;
        if (i_ >= lines_.size() || lines_[i_].tok.size() != 1 || lines_[i_].tok[0] != "}")
          fail("expected \"}\" closing the End Site");
        ++i_;
      } else {
        fail("unexpected \"" + k + "\" in joint \"" + j.name + "\"");
      }
    }
    if (!have_offset) fail("joint \"" + j.name + "\" has no OFFSET");
  }

  std::vector<Line> lines_;
  std::string what_;
  size_t i_ = 0;
};

const char* channel_name(BvhChannel c) {
  switch (c) {
    case BvhChannel::kXpos:
      return "Xposition";
    case BvhChannel::kYpos:
      return "Yposition";
    case BvhChannel::kZpos:
      return "Zposition";
    case BvhChannel::kXrot:
      return "Xrotation";
    case BvhChannel::kYrot:
      return "Yrotation";
    case BvhChannel::kZrot:
      return "Zrotation";
  }
  return "?";
}

std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6f", v);
  std::string s = buf;
  if (s == "-0.000000") s = "0.000000";
  return s;
}

void write_joint(const Bvh& b, int j, int depth, std::string& out, std::vector<int>& order) {
  order.push_back(j);
  const std::string ind(size_t(depth) * 2, ' ');
  const BvhJoint& J = b.joints[size_t(j)];
  out += ind + (J.parent < 0 ? "ROOT " : "JOINT ") + J.name + "\n" + ind + "{\n";
  out += ind + "  OFFSET " + num(J.offset.x()) + " " + num(J.offset.y()) + " " + num(J.offset.z()) +
         "\n";
  out += ind + "  CHANNELS " + std::to_string(J.channels.size());
  for (BvhChannel c : J.channels) out += std::string(" ") + channel_name(c);
  out += "\n";
  for (size_t k = 0; k < b.joints.size(); ++k)
    if (b.joints[k].parent == j) write_joint(b, int(k), depth + 1, out, order);
  if (J.has_end_site)
    out += ind + "  End Site\n" + ind + "  {\n" + ind + "    OFFSET " + num(J.end_site.x()) + " " +
           num(J.end_site.y()) + " " + num(J.end_site.z()) + "\n" + ind + "  }\n";
  out += ind + "}\n";
}

}  // namespace

Eigen::Matrix3d bvh_channel_rotation(BvhChannel c, double degrees) {
  const double a = degrees * kPi / 180.0;
  const Eigen::Vector3d axis = c == BvhChannel::kXrot   ? Eigen::Vector3d::UnitX()
                               : c == BvhChannel::kYrot ? Eigen::Vector3d::UnitY()
                                                        : Eigen::Vector3d::UnitZ();
  return Eigen::AngleAxisd(a, axis).toRotationMatrix();
}

int Bvh::num_channels() const {
  int n = 0;
  for (const auto& j : joints) n += int(j.channels.size());
  return n;
}

Eigen::Matrix3d Bvh::local_rotation(int j, int f) const {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  const BvhJoint& J = joints[size_t(j)];
  for (size_t c = 0; c < J.channels.size(); ++c) {
    const BvhChannel ch = J.channels[c];
    if (ch == BvhChannel::kXrot || ch == BvhChannel::kYrot || ch == BvhChannel::kZrot)
      R = R * bvh_channel_rotation(ch, frames(f, J.first_channel + int(c)));
  }
  return R;
}

Eigen::Vector3d Bvh::local_translation(int j, int f) const {
  const BvhJoint& J = joints[size_t(j)];
  Eigen::Vector3d t = J.offset;
  for (size_t c = 0; c < J.channels.size(); ++c) {
    const double v = frames(f, J.first_channel + int(c));
    if (J.channels[c] == BvhChannel::kXpos) t.x() += v;
    if (J.channels[c] == BvhChannel::kYpos) t.y() += v;
    if (J.channels[c] == BvhChannel::kZpos) t.z() += v;
  }
  return t;
}

Eigen::MatrixXd Bvh::rest_positions() const {
  Eigen::MatrixXd P(long(joints.size()), 3);
  for (size_t j = 0; j < joints.size(); ++j) {
    Eigen::Vector3d p = joints[j].offset;
    if (joints[j].parent >= 0) p += P.row(joints[j].parent).transpose();
    P.row(long(j)) = p.transpose();
  }
  return P;
}

int Bvh::find(const std::string& name) const {
  for (size_t j = 0; j < joints.size(); ++j)
    if (joints[j].name == name) return int(j);
  return -1;
}

Bvh parse_bvh(const std::string& text, const std::string& what) {
  return Parser(text, what).parse();
}

Bvh read_bvh(const std::string& path) {
  return parse_bvh(read_file_text(path), path);
}

std::string format_bvh(const Bvh& b) {
  if (b.joints.empty()) throw Error("bvh: no joints to write");
  if (b.frames.cols() != b.num_channels())
    throw Error("bvh: " + std::to_string(b.frames.cols()) + " values per frame for " +
                std::to_string(b.num_channels()) + " channels");
  for (size_t j = 1; j < b.joints.size(); ++j)
    if (b.joints[j].parent < 0 || b.joints[j].parent >= int(j))
      throw Error("bvh: joint " + std::to_string(j) +
                  " comes before its parent or is a second root");
  std::string out = "HIERARCHY\n";
  std::vector<int> order;  // the joints as written: the frames' values follow it
  write_joint(b, 0, 0, out, order);
  out += "MOTION\nFrames: " + std::to_string(b.frames.rows()) + "\n";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.8f", b.frame_time);
  out += std::string("Frame Time: ") + buf + "\n";
  for (long f = 0; f < b.frames.rows(); ++f) {
    bool first = true;
    for (int j : order) {
      const BvhJoint& J = b.joints[size_t(j)];
      for (size_t c = 0; c < J.channels.size(); ++c) {
        if (!first) out += ' ';
        out += num(b.frames(f, J.first_channel + long(c)));
        first = false;
      }
    }
    out += "\n";
  }
  return out;
}

void write_bvh(const std::string& path, const Bvh& bvh) {
  write_text_atomic(path, format_bvh(bvh));
}

}  // namespace ks
