// The commit the binary was built from, for `tessera --version`.
#pragma once

namespace tessera::cli {

/// The source tree's short git commit when the build ran (cli/write_commit.cmake writes it), or "unknown" when
/// it was built outside a git checkout.
const char* build_commit();

}  // namespace tessera::cli
