// The project's pages against the project: every `kinesplat <command>` that README.md names (in a
// code span or a fenced code block) is a command the built binary lists in its --help (and a
// second word that names a subcommand is one of that command's), and every relative markdown
// link in README.md, DEVELOPERS.md and docs/*.md resolves to a file relative to the linking page.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cli_run.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

const fs::path kRoot = fs::path(KS_SOURCE_DIR);

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

bool starts_with(const std::string& s, const std::string& prefix) {
  return s.compare(0, prefix.size(), prefix) == 0;
}

std::string trim_left(const std::string& s) {
  size_t i = 0;
  while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
  return s.substr(i);
}

bool is_fence(const std::string& line) {
  const std::string t = trim_left(line);
  return starts_with(t, "```") || starts_with(t, "~~~");
}

// A page split into its code (fenced blocks and inline code spans) and its prose (everything else,
// code replaced by spaces so that a link's text and target stay on their line).
struct Page {
  std::vector<std::string> code;  // each fenced block line and each inline span
  std::vector<std::string> prose_lines;
};

Page split_page(const std::string& text) {
  Page page;
  bool in_fence = false;
  for (const std::string& line : split_lines(text)) {
    if (is_fence(line)) {
      in_fence = !in_fence;
      page.prose_lines.emplace_back();
      continue;
    }
    if (in_fence) {
      page.code.push_back(line);
      page.prose_lines.emplace_back();
      continue;
    }
    std::string prose;
    size_t i = 0;
    while (i < line.size()) {
      if (line[i] != '`') {
        prose += line[i++];
        continue;
      }
      size_t ticks = 0;
      while (i + ticks < line.size() && line[i + ticks] == '`') ++ticks;
      const std::string delim(ticks, '`');
      const size_t end = line.find(delim, i + ticks);
      if (end == std::string::npos) {  // an unmatched backtick is text
        prose += line.substr(i, ticks);
        i += ticks;
        continue;
      }
      page.code.push_back(line.substr(i + ticks, end - i - ticks));
      prose += std::string(end + ticks - i, ' ');
      i = end + ticks;
    }
    page.prose_lines.push_back(prose);
  }
  return page;
}

bool word_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_';
}

// The words after each "kinesplat" (the program name alone, or a path ending in it) in a code
// fragment: {first, second} where second is empty unless it looks like a subcommand name
// (lower-case letters, digits and dashes; no file name, option or placeholder).
std::vector<std::pair<std::string, std::string>> commands_in(const std::string& code) {
  std::vector<std::pair<std::string, std::string>> found;
  const std::string name = "kinesplat";
  auto next_word = [&](size_t& pos) {
    while (pos < code.size() && (code[pos] == ' ' || code[pos] == '\t')) ++pos;
    const size_t start = pos;
    while (pos < code.size() && !std::isspace(static_cast<unsigned char>(code[pos])) &&
           code[pos] != '`' && code[pos] != '|' && code[pos] != ';' && code[pos] != ')')
      ++pos;
    return code.substr(start, pos - start);
  };
  auto is_name = [](const std::string& w) {
    if (w.empty() || !std::islower(static_cast<unsigned char>(w[0]))) return false;
    return std::all_of(w.begin(), w.end(), [](char c) {
      return std::islower(static_cast<unsigned char>(c)) ||
             std::isdigit(static_cast<unsigned char>(c)) || c == '-';
    });
  };
  for (size_t at = code.find(name); at != std::string::npos; at = code.find(name, at + 1)) {
    const size_t after = at + name.size();
    if (at > 0 && (word_char(code[at - 1]) || code[at - 1] == '.')) continue;  // foo_kinesplat
    if (after >= code.size() || (code[after] != ' ' && code[after] != '\t')) continue;
    size_t pos = after;
    const std::string first = next_word(pos);
    if (!is_name(first)) continue;  // `kinesplat --help`, `kinesplat PHOTO`
    size_t pos2 = pos;
    std::string second = next_word(pos2);
    if (!is_name(second)) second.clear();
    found.emplace_back(first, second);
  }
  return found;
}

// The subcommand names a CLI11 help text lists (the lines under its "Subcommands:" heading).
std::set<std::string> subcommands_in_help(const std::string& help) {
  std::set<std::string> names;
  bool in_list = false;
  for (const std::string& line : split_lines(help)) {
    std::string lower = line;
    std::transform(lower.begin(), lower.end(), lower.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (starts_with(trim_left(lower), "subcommands:")) {
      in_list = true;
      continue;
    }
    if (!in_list) continue;
    if (trim_left(line).empty()) {
      if (!names.empty()) in_list = false;
      continue;
    }
    if (line[0] != ' ') {  // the next heading
      in_list = false;
      continue;
    }
    std::istringstream words(line);
    std::string w;
    words >> w;
    if (!w.empty() && std::islower(static_cast<unsigned char>(w[0]))) names.insert(w);
  }
  return names;
}

std::set<std::string> subcommands_of(const std::string& args) {
  const test::CliRun r = test::run_cli(args + " --help");
  EXPECT_EQ(r.status, 0) << "kinesplat " << args << " --help: " << r.output;
  return subcommands_in_help(r.out);
}

// Markdown link targets `[text](target)` / `![alt](target)` in a page's prose, with the line they
// are on.
struct Link {
  std::string target;
  size_t line = 0;
};

std::vector<Link> links_in(const Page& page) {
  std::vector<Link> links;
  for (size_t n = 0; n < page.prose_lines.size(); ++n) {
    const std::string& s = page.prose_lines[n];
    for (size_t i = s.find("]("); i != std::string::npos; i = s.find("](", i + 2)) {
      const size_t end = s.find(')', i + 2);
      if (end == std::string::npos) continue;
      std::string target = s.substr(i + 2, end - i - 2);
      // `[text](path "title")`: the path alone.
      const size_t space = target.find(' ');
      if (space != std::string::npos) target = target.substr(0, space);
      if (target.size() > 1 && target.front() == '<' && target.back() == '>')
        target = target.substr(1, target.size() - 2);
      if (target.empty()) continue;
      links.push_back({target, n + 1});
    }
  }
  return links;
}

bool external(const std::string& target) {
  return starts_with(target, "http://") || starts_with(target, "https://") ||
         starts_with(target, "mailto:") || target[0] == '#';
}

std::vector<fs::path> linked_pages() {
  std::vector<fs::path> pages = {kRoot / "README.md", kRoot / "DEVELOPERS.md"};
  std::vector<fs::path> docs;
  for (const auto& e : fs::directory_iterator(kRoot / "docs"))
    if (e.is_regular_file() && e.path().extension() == ".md") docs.push_back(e.path());
  std::sort(docs.begin(), docs.end());
  pages.insert(pages.end(), docs.begin(), docs.end());
  return pages;
}

TEST(DocsLinks, PageSplitterSeparatesCodeFromProse) {
  const Page p = split_page(
      "See [a](docs/a.md) and `kinesplat view A` or ``x ` y``.\n"
      "```sh\nkinesplat create photo.png --out me\n[not](a-link.md)\n```\n");
  ASSERT_EQ(p.code.size(), 4u);
  EXPECT_EQ(p.code[0], "kinesplat view A");
  EXPECT_EQ(p.code[1], "x ` y");
  EXPECT_EQ(p.code[2], "kinesplat create photo.png --out me");
  const auto links = links_in(p);
  ASSERT_EQ(links.size(), 1u);  // the one in the fenced block is code
  EXPECT_EQ(links[0].target, "docs/a.md");
  EXPECT_EQ(links[0].line, 1u);
}

TEST(DocsLinks, CommandsAreTakenFromCode) {
  const auto c = commands_in("./build/kinesplat bench raster --gaussians 1; kinesplat create PHOTO");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0], std::make_pair(std::string("bench"), std::string("raster")));
  EXPECT_EQ(c[1], std::make_pair(std::string("create"), std::string()));
  EXPECT_TRUE(commands_in("kinesplat --help").empty());
  EXPECT_TRUE(commands_in("kinesplat_tests --gtest_filter=X").empty());
  EXPECT_EQ(commands_in("kinesplat batch m.csv --out d").at(0).second, "");
  EXPECT_EQ(subcommands_in_help("Usage: x\n\nSubcommands:\n  body   Body\n  bench  B\n"),
            (std::set<std::string>{"body", "bench"}));
}

TEST(DocsLinks, ReadmeCommandsExistInHelp) {
  const std::string readme = read_text(kRoot / "README.md");
  ASSERT_FALSE(readme.empty()) << (kRoot / "README.md");
  const std::set<std::string> top = subcommands_of("");
  ASSERT_GE(top.size(), 10u) << "no command list in kinesplat --help";

  std::map<std::string, std::set<std::string>> named;  // command -> second words named after it
  for (const std::string& code : split_page(readme).code)
    for (const auto& [first, second] : commands_in(code)) named[first].insert(second);
  ASSERT_GE(named.size(), 5u) << "README.md names too few `kinesplat <command>`s";

  for (const auto& [command, seconds] : named) {
    ASSERT_TRUE(top.count(command)) << "README.md names `kinesplat " << command
                                    << "`, which kinesplat --help does not list";
    const std::set<std::string> subs = subcommands_of(command);
    if (subs.empty()) continue;  // a command without subcommands takes its arguments
    for (const std::string& s : seconds) {
      if (s.empty()) continue;
      EXPECT_TRUE(subs.count(s)) << "README.md names `kinesplat " << command << " " << s
                                 << "`, which kinesplat " << command << " --help does not list";
    }
  }
}

TEST(DocsLinks, RelativeLinksResolve) {
  size_t checked = 0;
  std::vector<std::string> broken;
  for (const fs::path& page : linked_pages()) {
    const std::string text = read_text(page);
    ASSERT_FALSE(text.empty()) << page;
    for (const Link& link : links_in(split_page(text))) {
      if (external(link.target)) continue;
      std::string path = link.target;
      const size_t hash = path.find('#');
      if (hash != std::string::npos) path = path.substr(0, hash);
      if (path.empty()) continue;
      ++checked;
      const fs::path resolved = page.parent_path() / path;
      if (!fs::exists(resolved))
        broken.push_back(fs::relative(page, kRoot).string() + ":" + std::to_string(link.line) +
                         ": " + link.target);
    }
  }
  EXPECT_GE(checked, 20u) << "too few relative links found to check";
  std::string list;
  for (const auto& b : broken) list += "\n  " + b;
  EXPECT_TRUE(broken.empty()) << broken.size() << " broken relative links:" << list;
}

}  // namespace
}  // namespace ks
