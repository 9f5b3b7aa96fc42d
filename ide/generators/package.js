// ROS 2 packages (ament_python) of the IDE's programs, as a ROS 2 course's students make them:
//   PKG/package.xml            its dependencies: rclpy and the packages of the types its programs use
//   PKG/setup.py, setup.cfg    one console-script entry point per program (ros2 run PKG PROGRAM)
//   PKG/resource/PKG           the ament index marker
//   PKG/PKG/PROGRAM.py         each program: a block program's node (generators/node.js), a text
//                              program as it is written (a roslibpy one with the runtime bundled)
//   PKG/launch/PKG.launch.py   with several programs: a launch file starting them all
//   PKG/README.md
import { gen as nodeGen, rosUses, safeIdent } from './node.js';
import { gen as pyGen } from './python.js';

const xml = (s) => String(s).replace(/&/g, '&amp;').replace(/</g, '&lt;').replace(/>/g, '&gt;');
const ANY_TYPE = /['"]([a-z][a-z0-9_]*)\/(?:msg|srv|action)\/[A-Z]\w*['"]/g;
const HAS_MAIN = /^def main\(/m;
const RCLPY = /^\s*(import rclpy\b|from rclpy(\.\w+)* import )/m;

// The block program in `workspace` as a node's Python (the code panel shows the same).
export function blockNode(workspace, { programName, namespace = '', scope = null }) {
  const name = safeIdent(programName, 'program');
  nodeGen.scope = scope ?? pyGen.scope;   // the page's robot namespace, graph and types (generators/scope.js)
  nodeGen.programName = programName;
  nodeGen.namespace = namespace;
  nodeGen.packageName = name;
  nodeGen.nodeName = name;
  nodeGen.className = name.split('_').filter(Boolean).map((w) => w[0].toUpperCase() + w.slice(1)).join('') || 'Program';
  if (/^\d/.test(nodeGen.className)) nodeGen.className = `Program${nodeGen.className}`;
  const code = nodeGen.workspaceToCode(workspace);
  return { name, code, missingTypes: [...nodeGen.missingTypes_] };
}

// The ROS packages a program's Python uses: its imports of message modules, and the types it names
// as strings (a roslibpy program's 'geometry_msgs/msg/Twist').
export function dependencies(code) {
  const deps = new Set(rosUses(code).packages);
  if (!RCLPY.test(code)) deps.delete('rclpy');
  for (const m of code.matchAll(ANY_TYPE)) deps.add(m[1]);
  return [...deps].sort();
}

/**
 * {pkg, files: {path: text}} of a package. programs: [{name, code}] (name: the program's name as
 * the IDE shows it; code: its Python). One entry point each; a launch file when there are several.
 */
export function rosPackage(packageName, programs) {
  const pkg = safeIdent(packageName, 'rosgate_programs');
  const used = new Set();
  const entries = programs.map((p) => {
    let exe = safeIdent(p.name, 'program');
    while (used.has(exe) || exe === pkg && programs.length > 1) exe += '_';
    used.add(exe);
    const node = RCLPY.test(p.code);
    // an rclpy program's main() is its entry point; any other runs as a script (ros2 run runs it)
    return { ...p, exe, node, main: node && HAS_MAIN.test(p.code), roslibpy: /\bimport roslibpy\b|rosgate_runtime/.test(p.code) };
  });
  const deps = new Set();
  for (const e of entries) for (const d of dependencies(e.code)) deps.add(d);
  const launch = entries.length > 1;
  if (launch) { deps.add('launch'); deps.add('launch_ros'); }
  const about = entries.length > 1
    ? `${entries.map((e) => e.name).join(', ')}: programs of the rosgate IDE`
    : `${entries[0].name}: a program of the rosgate IDE`;
  const files = {};
  const scripts = [];
  for (const e of entries) {
    files[`${pkg}/${e.exe}.py`] = e.code;
    if (e.main) {
      scripts.push(`${e.exe} = ${pkg}.${e.exe}:main`);
    } else {      // a program of top-level lines: run as ros2 run runs a script
      files[`${pkg}/${e.exe}_main.py`] = `"""Runs ${e.exe}.py as a script (its lines run at the top level)."""\nimport runpy\n\n\n` +
        `def main():\n    runpy.run_module(${JSON.stringify(`${pkg}.${e.exe}`)}, run_name='__main__')\n`;
      scripts.push(`${e.exe} = ${pkg}.${e.exe}_main:main`);
    }
  }
  files[`${pkg}/__init__.py`] = '';
  files[`resource/${pkg}`] = '';
  files['package.xml'] = `<?xml version="1.0"?>
<?xml-model href="http://download.ros.org/schema/package_format3.xsd" schematypens="http://www.w3.org/2001/XMLSchema"?>
<package format="3">
  <name>${pkg}</name>
  <version>0.1.0</version>
  <description>${xml(about)}</description>
  <maintainer email="student@example.com">student</maintainer>
  <license>Apache-2.0</license>

${[...deps].sort().map((d) => `  <exec_depend>${d}</exec_depend>`).join('\n')}

  <export>
    <build_type>ament_python</build_type>
  </export>
</package>
`;
  files['setup.py'] = `${launch ? 'from glob import glob\n\n' : ''}from setuptools import setup

package_name = ${JSON.stringify(pkg)}

setup(
    name=package_name,
    version="0.1.0",
    packages=[package_name],
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),${launch ? '\n        ("share/" + package_name + "/launch", glob("launch/*.launch.py")),' : ''}
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="student",
    maintainer_email="student@example.com",
    description=${JSON.stringify(about)},
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
${scripts.map((s) => `            ${JSON.stringify(s)},`).join('\n')}
        ],
    },
)
`;
  files['setup.cfg'] = `[develop]\nscript_dir=$base/lib/${pkg}\n[install]\ninstall_scripts=$base/lib/${pkg}\n`;
  if (launch) {
    files[`launch/${pkg}.launch.py`] = `"""Starts ${entries.map((e) => e.exe).join(', ')}: ros2 launch ${pkg} ${pkg}.launch.py"""
from launch import LaunchDescription
from launch_ros.actions import Node


def generate_launch_description():
    return LaunchDescription([
${entries.map((e) => `        Node(package=${JSON.stringify(pkg)}, executable=${JSON.stringify(e.exe)}, output='screen'),`).join('\n')}
    ])
`;
  }
  const run = entries.map((e) => `    ros2 run ${pkg} ${e.exe}`).join('\n');
  const needsRoslibpy = entries.some((e) => e.roslibpy);
  files['README.md'] = `# ${pkg}

${about}, made by the rosgate IDE. Put this folder in the \`src/\` folder of a colcon workspace
on a ROS 2 (Jazzy) machine, then:

    colcon build
    source install/setup.bash
${run}
${launch ? `\nor all of them at once:\n\n    ros2 launch ${pkg} ${pkg}.launch.py\n` : ''}
In a robot namespace: \`ros2 run ${pkg} ${entries[0].exe} --ros-args -r __ns:=/s07\`.
Ctrl-C stops a program and its robot.
${needsRoslibpy ? `
${entries.filter((e) => e.roslibpy).map((e) => e.exe).join(', ')} talk to a rosbridge server (the rosgate gateway) rather than
to the ROS graph: they need roslibpy (\`pip install roslibpy\`) and take \`--url ws://HOST:9090/\`.
` : ''}
Dependencies (package.xml): ${[...deps].sort().join(', ')}.
`;
  return { pkg, files: Object.fromEntries(Object.entries(files).map(([p, t]) => [`${pkg}/${p}`, t])) };
}
