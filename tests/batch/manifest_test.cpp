#include "batch/manifest.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include "core/error.hpp"
#include "temp_dir.hpp"

namespace {

const ks::ItemOptionSpec kSpec = {{"steps", true}, {"generator", true}, {"force", false}};

void touch(const std::string& path) {
  std::ofstream(path) << "x";
}

std::string error_of(const std::string& text, const std::string& name, const std::string& base) {
  try {
    ks::parse_manifest_text(text, name, base, kSpec);
  } catch (const ks::Error& e) {
    return e.what();
  }
  return "";
}

TEST(BatchManifest, CsvWithOptionsFlagsQuotesAndComments) {
  ks::test::TempDir dir("ks_batch");
  touch(dir / "a.png");
  touch(dir / "b c.png");
  const std::string text =
      "# photos of the team\n"
      "id,photo,steps,force,generator\n"
      "a,a.png,20,,\n"
      "\n"
      "b,\"b c.png\",,true,\"lift\"\r\n";
  const ks::Manifest m = ks::parse_manifest_text(text, "m.csv", dir.str(), kSpec);
  ASSERT_EQ(m.items.size(), 2u);
  EXPECT_EQ(m.items[0].id, "a");
  EXPECT_EQ(m.items[0].photo, dir / "a.png");
  EXPECT_EQ(m.items[0].line, 3);
  ASSERT_EQ(m.items[0].options.size(), 1u);
  EXPECT_EQ(m.items[0].options[0].name, "steps");
  EXPECT_EQ(m.items[0].options[0].value, "20");
  EXPECT_FALSE(m.items[0].options[0].flag);
  EXPECT_EQ(m.items[1].photo, dir / "b c.png");
  EXPECT_EQ(m.items[1].line, 5);
  ASSERT_EQ(m.items[1].options.size(), 2u);
  EXPECT_EQ(m.items[1].options[0].name, "force");
  EXPECT_TRUE(m.items[1].options[0].flag);
  EXPECT_EQ(m.items[1].options[1].value, "lift");
}

TEST(BatchManifest, JsonLinesWithNumbersBooleansAndNulls) {
  ks::test::TempDir dir("ks_batch");
  touch(dir / "a.png");
  touch(dir / "b.png");
  const std::string text =
      "{\"id\": \"a\", \"photo\": \"a.png\", \"steps\": 20, \"force\": false}\n"
      "{\"id\": \"b\", \"photo\": \"" +
      (dir / "b.png") + "\", \"--force\": true, \"generator\": null}\n";
  const ks::Manifest m = ks::parse_manifest_text(text, "m.jsonl", dir.str(), kSpec);
  ASSERT_EQ(m.items.size(), 2u);
  ASSERT_EQ(m.items[0].options.size(), 1u);
  EXPECT_EQ(m.items[0].options[0].value, "20");
  EXPECT_EQ(m.items[1].photo, dir / "b.png");  // absolute paths stay
  ASSERT_EQ(m.items[1].options.size(), 1u);
  EXPECT_TRUE(m.items[1].options[0].flag);
  // Sniffed without the extension.
  EXPECT_EQ(ks::parse_manifest_text(text, "m.txt", dir.str(), kSpec).items.size(), 2u);
}

TEST(BatchManifest, EveryProblemReportedAtOnce) {
  ks::test::TempDir dir("ks_batch");
  touch(dir / "a.png");
  const std::string text =
      "id,photo,steps,stepz,force\n"
      "a,a.png,20,,\n"
      "a,a.png,,,\n"        // duplicate id
      "b,missing.png,,,\n"  // missing photo
      "c,a.png,,3,\n"       // a value in the unknown column (reported once, on the header)
      "../d,a.png,,,\n"     // id not a folder name
      "e,a.png,,,maybe\n"   // flag with a value
      "f,a.png\n";          // too few fields
  const std::string err = error_of(text, "m.csv", dir.str());
  EXPECT_NE(err.find("m.csv: 6 problems, nothing was run"), std::string::npos) << err;
  EXPECT_NE(err.find("m.csv: line 3: duplicate id 'a' (first on line 2)"), std::string::npos)
      << err;
  EXPECT_NE(err.find("line 4: photo " + (dir / "missing.png") + " does not exist"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("line 1: unknown option 'stepz'"), std::string::npos) << err;
  EXPECT_NE(err.find("line 6: id '../d' is not usable"), std::string::npos) << err;
  EXPECT_NE(err.find("line 7: option 'force' is a flag"), std::string::npos) << err;
  EXPECT_NE(err.find("line 8: 2 fields, the header has 5"), std::string::npos) << err;
}

TEST(BatchManifest, MalformedInputs) {
  ks::test::TempDir dir("ks_batch");
  touch(dir / "a.png");
  const std::string b = dir.str();
  EXPECT_NE(error_of("", "m.csv", b).find("no items"), std::string::npos);
  EXPECT_NE(error_of("id,photo\n", "m.csv", b).find("no items"), std::string::npos);
  EXPECT_NE(error_of("name,photo\nx,a.png\n", "m.csv", b).find("no 'id' column"),
            std::string::npos);
  EXPECT_NE(error_of("id,photo\na,\"a.png\n", "m.csv", b).find("line 2: unterminated quoted"),
            std::string::npos);
  EXPECT_NE(error_of("id,photo\na,\"a.png\"x\n", "m.csv", b).find("text after a closing quote"),
            std::string::npos);
  EXPECT_NE(error_of("id,photo,photo\na,a.png,a.png\n", "m.csv", b).find("column 'photo' twice"),
            std::string::npos);
  EXPECT_NE(error_of("id,photo,out\na,a.png,x\n", "m.csv", b).find("'out' is set by batch"),
            std::string::npos);
  EXPECT_NE(error_of("{\"id\": \"a\", \"photo\": \"a.png\"\n", "m.jsonl", b).find("not valid JSON"),
            std::string::npos);
  EXPECT_NE(error_of("[1]\n", "m.jsonl", b).find("expected a JSON object"), std::string::npos);
  EXPECT_NE(error_of("{\"id\": \"a\", \"photo\": \"a.png\", \"steps\": [1]}\n", "m.jsonl", b)
                .find("'steps' is an array"),
            std::string::npos);
  EXPECT_NE(error_of("{\"photo\": \"a.png\"}\n", "m.jsonl", b).find("line 1: no id"),
            std::string::npos);
  EXPECT_NE(error_of("{\"id\": \"a\", \"photo\": \".\"}\n", "m.jsonl", b).find("is not a file"),
            std::string::npos);
  EXPECT_THROW(ks::parse_manifest(dir / "none.csv", kSpec), ks::Error);
}

TEST(BatchManifest, CsvFieldsAndIds) {
  std::vector<std::string> errors;
  const auto recs = ks::parse_csv("a, \"b,\"\"c\"\"\" ,d\n\"multi\nline\",x,\n", errors);
  ASSERT_TRUE(errors.empty());
  ASSERT_EQ(recs.size(), 2u);
  EXPECT_EQ(recs[0].fields, (std::vector<std::string>{"a", "b,\"c\"", "d"}));
  EXPECT_EQ(recs[1].line, 2);
  EXPECT_EQ(recs[1].fields, (std::vector<std::string>{"multi\nline", "x", ""}));
  EXPECT_TRUE(ks::valid_item_id("person_01.v2-b"));
  EXPECT_FALSE(ks::valid_item_id(""));
  EXPECT_FALSE(ks::valid_item_id(".hidden"));
  EXPECT_FALSE(ks::valid_item_id("-x"));
  EXPECT_FALSE(ks::valid_item_id("a b"));
  EXPECT_FALSE(ks::valid_item_id("a/b"));
  EXPECT_FALSE(ks::valid_item_id(std::string(65, 'a')));
}

}  // namespace
