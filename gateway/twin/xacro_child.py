"""Expands one xacro text, in a process of its own (``description.expand`` starts it as a script:
``python -I xacro_child.py``, no gateway module imported).

Standard input: JSON ``{"text", "filename", "roots", "readable", "limits": [cpu_s, memory_bytes]}``;
standard output: JSON ``{"urdf"}`` or ``{"error"}``. PyPI's xacro does the expansion (its
``process_doc``, as ``xacro FILE`` does), with two changes made here:

- ``$(find PKG)`` is the folder PKG in the first of ``roots`` that has it (the gateway's package
  roots: AMENT_PREFIX_PATH's share folders, then --mesh-path): no ament index is needed, and a
  description's meshes resolve to what /package/ serves;
- every file xacro opens (``xacro:include``, ``xacro.load_yaml``) must lie under one of
  ``readable`` (its real path): a description from the graph cannot make the gateway read a file
  outside the robot's packages.

xacro's expressions are Python evaluated with its own guard (no ``__`` names, a few builtins); this
process is why that guard is not the only one: its CPU time and memory are capped (``limits``),
the parent gives it an empty environment for a description from the graph (``$(env ...)`` fails,
``$(optenv ...)`` takes its default) and a deadline, and reads at most a bounded answer.
"""

from __future__ import annotations

import io
import json
import os
import re
import resource
import sys

PACKAGE = re.compile(r'[A-Za-z0-9_][A-Za-z0-9_-]{0,99}')


def main() -> int:
    request = json.loads(sys.stdin.buffer.read())
    cpu, memory = request['limits']
    resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu))
    resource.setrlimit(resource.RLIMIT_AS, (memory, memory))
    roots = [os.path.realpath(r) for r in request['roots']]
    readable = [os.path.realpath(r) for r in request['readable']]
    out = sys.stdout
    sys.stdout = io.StringIO()     # xacro prints warnings there
    try:
        import xacro
        from xacro import substitution_args
        from xml.dom.minidom import parseString

        def find(package: str) -> str:
            if not PACKAGE.fullmatch(package):
                raise xacro.XacroException(f'$(find {package[:60]}): not a package name')
            for root in roots:
                folder = os.path.join(root, package)
                if os.path.isdir(folder):
                    return folder
            raise xacro.XacroException(f'$(find {package}): no package {package} under the package roots '
                                       '(AMENT_PREFIX_PATH\'s share folders, --mesh-path)')

        def guarded_open(path, *args, **kwargs):
            real = os.path.realpath(path)
            if not any(real == r or real.startswith(r.rstrip(os.sep) + os.sep) for r in readable):
                raise OSError(13, 'outside the robot\'s packages (the package roots, --mesh-path)', str(path))
            return open(path, *args, **kwargs)

        substitution_args._eval_find = find
        substitution_args._eval_dict['find'] = find
        xacro.open = guarded_open          # what xacro.parse and xacro.load_yaml open files with
        xacro.init_stacks(request.get('filename'))   # relative includes: beside it (absolute), or nowhere
        doc = parseString(request['text'])
        xacro.process_doc(doc)
        answer = {'urdf': doc.toprettyxml(indent='  ')}
    except MemoryError:
        answer = {'error': 'xacro ran out of the memory it may use'}
    except Exception as e:   # xacro's errors, the XML parser's, a guarded open's
        answer = {'error': f'{type(e).__name__}: {e}'[:2000]}
    out.buffer.write(json.dumps(answer).encode())
    out.flush()
    return 0 if 'urdf' in answer else 1


if __name__ == '__main__':
    sys.exit(main())
