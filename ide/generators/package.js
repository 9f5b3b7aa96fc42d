// A block program as a ROS 2 package (ament_python) that builds with colcon and runs with ros2 run:
//   PKG/package.xml            its dependencies: rclpy and the packages of the types the program names
//   PKG/setup.py, setup.cfg    the console-script entry point NODE = PKG.NODE:main
//   PKG/resource/PKG           the ament index marker
//   PKG/PKG/NODE.py            the node (generators/node.js)
//   PKG/PKG/rosgate_node.py    its runtime over rclpy, and rosgate_runtime.py, the blocks' helpers
//   PKG/README.md
import { gen as nodeGen, rosUses, safeIdent } from './node.js';
import { gen as pyGen } from './python.js';

const xml = (s) => String(s).replace(/&/g, '&amp;').replace(/</g, '&lt;').replace(/>/g, '&gt;');

// {path: text} of the package; `runtime` = {rosgate_runtime.py, rosgate_node.py} texts.
export function rosPackage(workspace, { programName, namespace = '', runtime }) {
  const pkg = safeIdent(programName, 'rosgate_program');
  const node = `${pkg}_node`;
  nodeGen.scope = pyGen.scope;         // the page's robot namespace and graph (generators/scope.js)
  nodeGen.programName = programName;
  nodeGen.namespace = namespace;
  nodeGen.packageName = pkg;
  nodeGen.nodeName = node;
  const code = nodeGen.workspaceToCode(workspace);
  const deps = rosUses(code).packages;
  const about = `${programName}: a rosgate block program as a ROS 2 node`;
  const files = {
    'package.xml': `<?xml version="1.0"?>
<?xml-model href="http://download.ros.org/schema/package_format3.xsd" schematypens="http://www.w3.org/2001/XMLSchema"?>
<package format="3">
  <name>${pkg}</name>
  <version>0.1.0</version>
  <description>${xml(about)}</description>
  <maintainer email="student@example.com">student</maintainer>
  <license>Apache-2.0</license>

${deps.map((d) => `  <exec_depend>${d}</exec_depend>`).join('\n')}

  <export>
    <build_type>ament_python</build_type>
  </export>
</package>
`,
    'setup.py': `from setuptools import setup

package_name = ${JSON.stringify(pkg)}

setup(
    name=package_name,
    version="0.1.0",
    packages=[package_name],
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="student",
    maintainer_email="student@example.com",
    description=${JSON.stringify(about)},
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            ${JSON.stringify(`${node} = ${pkg}.${node}:main`)},
        ],
    },
)
`,
    'setup.cfg': `[develop]\nscript_dir=$base/lib/${pkg}\n[install]\ninstall_scripts=$base/lib/${pkg}\n`,
    [`resource/${pkg}`]: '',
    [`${pkg}/__init__.py`]: '',
    [`${pkg}/${node}.py`]: code,
    [`${pkg}/rosgate_node.py`]: runtime['rosgate_node.py'],
    [`${pkg}/rosgate_runtime.py`]: runtime['rosgate_runtime.py'],
    'README.md': `# ${pkg}

${about}, made by the rosgate IDE. Put this folder in the \`src/\` folder of a colcon workspace
on a ROS 2 (Jazzy) machine, then:

    colcon build
    source install/setup.bash
    ros2 run ${pkg} ${node}

In a robot namespace: \`ros2 run ${pkg} ${node} --ros-args -r __ns:=/s07\`.
Ctrl-C stops the program and publishes zero velocity.

Dependencies (package.xml): ${deps.join(', ')}.
`,
  };
  return { pkg, node, code, files: Object.fromEntries(Object.entries(files).map(([p, t]) => [`${pkg}/${p}`, t])) };
}
