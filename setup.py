"""Build steps only: the project's metadata and dependencies are in pyproject.toml.

The wheel (and a colcon install) carries the built IDE and the example programs as package data in
gateway/_assets/, so an installed rosgate serves them without the checkout and without Node. The IDE
must have been built first (`make ide`: npm ci && npm run build in ide/); the sdist carries the
built IDE, so a wheel built from it needs no Node either.
"""

import shutil
from pathlib import Path

from setuptools import Distribution, setup
from setuptools.command.build_py import build_py
from setuptools.command.sdist import sdist

HERE = Path(__file__).resolve().parent
# Sources of the IDE's build and its developer notes; everything else in ide/ is served.
IDE_BUILD_ONLY = ('node_modules', 'package.json', 'package-lock.json', 'build.mjs', 'README.md', '.*', '__pycache__')
IDE_BUILT = ('vendor/roslib.mjs', 'vendor/nipplejs.mjs', 'vendor/uplot.mjs', 'vendor/blockly/blockly_compressed.js',
             'vendor/blockly/media', 'vendor/pyodide/pyodide.mjs')


def require_built_ide() -> None:
    missing = [f for f in IDE_BUILT if not (HERE / 'ide' / f).exists()]
    if missing:
        raise SystemExit(f"rosgate: the IDE is not built (missing ide/{', ide/'.join(missing)}). "
                         'Run `make ide` (or `npm ci && npm run build` in ide/) before building the package.')


class BuildPyWithAssets(build_py):
    """Copies ide/ (without its build sources) and examples/ into gateway/_assets/."""

    def run(self):
        super().run()
        if self.editable_mode:   # an editable install serves the checkout's own ide/ and examples/
            return
        require_built_ide()
        target = Path(self.build_lib) / 'gateway' / '_assets'
        shutil.rmtree(target, ignore_errors=True)
        shutil.copytree(HERE / 'ide', target / 'ide', ignore=shutil.ignore_patterns(*IDE_BUILD_ONLY))
        shutil.copytree(HERE / 'examples', target / 'examples', ignore=shutil.ignore_patterns('.*', '__pycache__'))


class SdistWithBuiltIde(sdist):
    def run(self):
        require_built_ide()
        super().run()


class PlainValuesDistribution(Distribution):
    """colcon reads the configured setup() values back with ast.literal_eval: keep Requires-Python a string."""

    def parse_config_files(self, *args, **kwargs):
        super().parse_config_files(*args, **kwargs)
        for holder in (self, self.metadata):
            if getattr(holder, 'python_requires', None) is not None:
                holder.python_requires = str(holder.python_requires)


def link_metadata_into_colcon_build_dir() -> None:
    """`colcon build --symlink-install` runs this file through a symlink in its build directory, where
    it links setup.py, setup.cfg and the packages but not pyproject.toml: link the metadata too."""
    cwd = Path.cwd()
    if cwd == HERE or not (cwd / 'setup.py').is_symlink() or (cwd / 'setup.py').resolve() != HERE / 'setup.py':
        return
    for name in ('pyproject.toml', 'README.md'):
        if not (cwd / name).exists():
            (cwd / name).symlink_to(HERE / name)


link_metadata_into_colcon_build_dir()
setup(cmdclass={'build_py': BuildPyWithAssets, 'sdist': SdistWithBuiltIde}, distclass=PlainValuesDistribution)
