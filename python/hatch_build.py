"""Builds geomint.local's compiled module (crates/geomint-py) into the wheel when it can.

`pip install ./python` from a checkout of the repository, with a Rust toolchain (`cargo`) on the
PATH, compiles the module with cargo (the release profile: the integrator core at full speed) and
puts it beside the package, so `geomint.local` works without a server. Without cargo, or from an
sdist (which has no Rust sources), the wheel is the pure-Python client and geomint.local says how
to build the module. GEOMINT_BUILD_NATIVE=0 skips the module (scripts/test-python installs the
one the test build made instead), =1 makes a failure to build it an error."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any, Dict

from hatchling.builders.hooks.plugin.interface import BuildHookInterface

LIBRARY = {"linux": "libgeomint_native.so", "darwin": "libgeomint_native.dylib", "win32": "geomint_native.dll"}


class NativeModuleHook(BuildHookInterface):  # type: ignore[misc]
    """Compiles the module and force-includes it in a platform wheel."""

    PLUGIN_NAME = "custom"

    def initialize(self, version: str, build_data: Dict[str, Any]) -> None:
        if self.target_name != "wheel":
            return
        wanted = os.environ.get("GEOMINT_BUILD_NATIVE", "auto")
        if wanted == "0":
            return
        root = Path(self.root).resolve().parent
        manifest = root / "crates" / "geomint-py" / "Cargo.toml"
        cargo = shutil.which("cargo")
        if not manifest.is_file() or cargo is None:
            why = "no Rust sources beside python/" if not manifest.is_file() else "no cargo on the PATH"
            if wanted == "1":
                raise RuntimeError(f"GEOMINT_BUILD_NATIVE=1, but the module cannot be built: {why}")
            self.app.display_info(f"geomint: geomint.local's compiled module is not built ({why})")
            return
        target = Path(os.environ.get("CARGO_TARGET_DIR") or root / "target")
        env = dict(os.environ, PYO3_BUILD_EXTENSION_MODULE="1", PYO3_PYTHON=sys.executable)
        command = [cargo, "build", "--release", "--lib", "--manifest-path", str(manifest),
                   "--target-dir", str(target)]
        self.app.display_info("geomint: compiling geomint.local's module: " + " ".join(command))
        try:
            subprocess.run(command, check=True, env=env)
        except (OSError, subprocess.CalledProcessError) as e:
            if wanted == "1":
                raise
            self.app.display_warning(f"geomint: geomint.local's compiled module failed to build ({e}); "
                                     "the client is installed without it")
            return
        platform = "win32" if sys.platform == "win32" else "darwin" if sys.platform == "darwin" else "linux"
        library = target / "release" / LIBRARY[platform]
        module = "geomint_native.pyd" if platform == "win32" else "geomint_native.abi3.so"
        build_data["force_include"][str(library)] = module
        build_data["force_include"][str(manifest.parent / "geomint_native.pyi")] = "geomint_native.pyi"
        build_data["pure_python"] = False
        build_data["infer_tag"] = True
