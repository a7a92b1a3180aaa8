// The studio's workspace: ids the server makes, records, one studio at a time, leftovers cleared,
// labels from client file names; the upload's type sniffing and sizes; the zip of a site.
#include "studio/workspace.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include <nlohmann/json.hpp>
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "io/zip_write.hpp"
#include "studio/upload.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;

namespace ks {
namespace {

fs::path write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

TEST(StudioWorkspace, AddsLoadsAndRemovesAvatars) {
  test::TempDir dir("studio_ws");
  const fs::path root = dir.path() / "ws";
  write(root / "uploads" / "upload-1.part", "half");
  write(root / "avatars" / "20260101-000000-abcd.new" / "photo.png", "half");
  Workspace ws(root.string());
  EXPECT_TRUE(fs::is_empty(ws.uploads())) << "an earlier upload was left";
  EXPECT_FALSE(fs::exists(root / "avatars" / "20260101-000000-abcd.new"));
  EXPECT_TRUE(ws.ids().empty());
  EXPECT_THROW(Workspace{root.string()}, Error);  // one studio per workspace

  TempFile up(write(ws.uploads() / "u.part", "\x89PNG"));
  const AvatarRecord r = ws.add(up, ImageType::kPng, "me.png");
  EXPECT_TRUE(up.path().empty());  // moved in
  EXPECT_TRUE(Workspace::valid_id(r.id)) << r.id;
  EXPECT_EQ(r.photo, "photo.png");
  EXPECT_TRUE(fs::is_regular_file(ws.avatar_dir(r.id) / "photo.png"));
  EXPECT_EQ(ws.ids(), std::vector<std::string>{r.id});
  AvatarRecord l = *ws.load(r.id);
  EXPECT_EQ(l.label, "me.png");
  EXPECT_EQ(l.state, "queued");
  l.state = "failed";
  l.error = "fit: no person";
  ws.save(l);
  EXPECT_EQ(ws.load(r.id)->error, "fit: no person");
  // A record whose photo name was edited to a path is not followed.
  nlohmann::json j = read_json((ws.avatar_dir(r.id) / "studio.json").string());
  j["photo"] = "../../../etc/passwd";
  write_json_atomic((ws.avatar_dir(r.id) / "studio.json").string(), j);
  EXPECT_EQ(ws.load(r.id)->photo, "");

  for (const char* bad : {"..", "../x", "20260101-000000-ABCD", "20260101-000000-abcd/..", "",
                          "20260101-000000-abcd.new", "x"}) {
    EXPECT_FALSE(Workspace::valid_id(bad)) << bad;
    EXPECT_THROW(ws.avatar_dir(bad), Error) << bad;
    EXPECT_FALSE(ws.load(bad)) << bad;
  }
  ws.remove(r.id);
  EXPECT_TRUE(ws.ids().empty());
  EXPECT_FALSE(fs::exists(ws.avatar_dir(r.id)));
}

TEST(StudioWorkspace, LabelsFromFileNames) {
  EXPECT_EQ(Workspace::clean_label("me.png"), "me.png");
  EXPECT_EQ(Workspace::clean_label("../../etc/passwd"), "passwd");
  EXPECT_EQ(Workspace::clean_label("C:\\Users\\me\\photo.jpg"), "photo.jpg");
  EXPECT_EQ(Workspace::clean_label("a\nb\tc\x7f.png"), "abc.png");
  EXPECT_EQ(Workspace::clean_label(""), "photo");
  EXPECT_EQ(Workspace::clean_label("dir/"), "photo");
  EXPECT_EQ(Workspace::clean_label("caf\xc3\xa9.png"), "caf\xc3\xa9.png");
  EXPECT_EQ(Workspace::clean_label("bad\xff\xfe.png"), "bad??.png");
  const std::string longname(200, 'x');
  EXPECT_EQ(Workspace::clean_label(longname).size(), 80u);
}

TEST(StudioUpload, TypesBySniffingAndSizes) {
  EXPECT_EQ(sniff_image("\x89PNG\r\n\x1a\n....", 12), ImageType::kPng);
  EXPECT_EQ(sniff_image("\xff\xd8\xff\xe0", 4), ImageType::kJpeg);
  EXPECT_EQ(sniff_image("\x89PNG\r\n", 6), ImageType::kUnknown);  // too short to tell
  EXPECT_EQ(sniff_image("GIF89a..", 8), ImageType::kUnknown);
  EXPECT_EQ(sniff_image("<html>..", 8), ImageType::kUnknown);
  EXPECT_STREQ(image_extension(ImageType::kJpeg), ".jpg");
  EXPECT_EQ(megabytes(size_t(50) << 20), "50 MB");
  EXPECT_EQ(megabytes(size_t(1.5 * (1 << 20))), "1.5 MB");
  EXPECT_EQ(megabytes(60000000), "57 MB");
}

TEST(StudioUpload, ZipsAFolder) {
  test::TempDir dir("studio_zip");
  write(dir.path() / "site" / "index.html", "<p>hi</p>");
  write(dir.path() / "site" / "motions" / "0_turn.json", "{}");
  const std::string zip = (dir.path() / "site.zip").string();
  write_zip_of_folder(zip, (dir.path() / "site").string(), "top/");
  const std::vector<uint8_t> bytes = read_file_bytes(zip);
  ASSERT_GT(bytes.size(), 22u);
  EXPECT_EQ(bytes[0], 'P');
  EXPECT_EQ(bytes[1], 'K');
  // Python's zipfile reads it back, entries and bytes (where python3 is installed).
  if (std::system("command -v python3 >/dev/null 2>&1") == 0) {
    const std::string check =
        "python3 -c \"import zipfile,sys; z=zipfile.ZipFile(sys.argv[1]); "
        "assert z.testzip() is None; "
        "assert z.namelist()==['top/index.html','top/motions/0_turn.json']; "
        "assert z.read('top/index.html')==b'<p>hi</p>'\" " +
        zip;
    EXPECT_EQ(std::system(check.c_str()), 0);
  }
}

}  // namespace
}  // namespace ks
