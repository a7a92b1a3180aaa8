#pragma once
// A stand-in for the kinesplat program in the studio's tests: a shell script that prints what
// `kinesplat create` prints (stage lines, progress lines, the end) and writes the files create
// and export write, in a fraction of a second; it sleeps in reconstruct for `sleep_seconds` (a
// child `sleep`, its pid appended to `pid_file`), and fails in fit while `fail_file` exists.
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace ks::test {

inline std::string fake_kinesplat(const std::filesystem::path& dir, double sleep_seconds,
                                  const std::string& fail_file, const std::string& pid_file) {
  const std::filesystem::path p = dir / "fake-kinesplat";
  std::ofstream f(p);
  f << "#!/bin/sh\n"
       "cmd=\"$1\"; shift\n"
       "case \"$cmd\" in\n"
       "create)\n"
       "  out=\"$3\"; mkdir -p \"$out/subject\"\n"
       "  echo \"create [1/7     0s] perceive\"\n"
       "  echo \"perceive: 512x768, keypoints detector (19 of 25)\"\n"
       "  printf 'png' > \"$out/subject/perceive_overlay.png\"\n"
       "  echo \"create [2/7     0s] fit\"\n"
       "  if [ -f '"
    << fail_file
    << "' ]; then echo 'error: fit: no person found in the photo' >&2; exit 1; fi\n"
       "  printf 'png' > \"$out/subject/fit_overlay.png\"\n"
       "  echo \"create [3/7     0s] sample\"\n"
       "  echo \"sample  50% (4/8)  elapsed 0.1s eta 0s\" >&2\n"
       "  echo \"create [4/7     0s] generate\"\n"
       "  echo \"create [5/7     0s] augment\"\n"
       "  echo \"create [6/7     0s] reconstruct\"\n"
       "  echo \"reconstruct  10% (2/20) loss 0.05 psnr 20.0 N 100 elapsed 0.1s eta 9s\" >&2\n"
       "  sleep "
    << sleep_seconds
    << " &\n"
       "  echo $$ $! >> '"
    << pid_file
    << "'\n"
       "  wait $!\n"
       "  echo \"reconstruct 100% (20/20) loss 0.05 psnr 20.0 N 100 elapsed 0.2s eta 0s\" >&2\n"
       "  printf 'avatar-bytes' > \"$out/avatar.ksavatar\"\n"
       "  echo \"create [7/7     1s] videos\"\n"
       "  printf 'mp4-turntable' > \"$out/turntable.mp4\"\n"
       "  printf 'mp4-dance' > \"$out/dance.mp4\"\n"
       "  printf "
       "'{\"status\":\"done\",\"stages\":{\"perceive\":{\"status\":\"done\",\"seconds\":0.1},"
       "\"fit\":{\"status\":\"done\",\"seconds\":0.1}},\"outputs\":{\"videos\":[\"%s\",\"%s\"]}}' "
       "\"$out/turntable.mp4\" \"$out/dance.mp4\" > \"$out/create.json\"\n"
       "  echo \"create: done in 1 s\"\n"
       "  ;;\n"
       "export)\n"
       "  kind=\"$2\"; target=\"$3\"\n"
       "  case \"$kind\" in\n"
       "    --web) mkdir -p \"$target\"; echo '<!doctype html><p>viewer</p>' > "
       "\"$target/index.html\";"
       " echo '{}' > \"$target/motions.json\"; echo '{}' > \"$target/skeleton.json\";;\n"
       "    *) printf 'export %s' \"$kind\" > \"$target\";;\n"
       "  esac\n"
       "  echo \"export: wrote $target\"\n"
       "  ;;\n"
       "*) echo \"error: unknown command $cmd\" >&2; exit 1;;\n"
       "esac\n";
  f.close();
  ::chmod(p.c_str(), 0755);
  return p.string();
}

}  // namespace ks::test
