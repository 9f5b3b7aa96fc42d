// What of a workspace is the program, and which robot the generic ROS blocks' names are in.
// Both generators and the IDE page read these rules, so Run, the code panel and the .py file agree.

// A loose block: a value block on its own on the workspace (dropped there, or bumped out of an
// input when another block was dropped into it). Every top-level stack of statements runs;
// a loose value belongs to no statement, so the program skips it (the page greys it).
export function isLoose(block) {
  return !!block.outputConnection && !block.getParent() && !block.isShadow();
}

// How a generic ROS block's name is written in code: in the robot namespace (rt.ns(name), which
// the .py file's --ns also moves) or as it is. On a page with a robot namespace NS (a station of
// a fleet):
//   a relative name ('turtle1/cmd_vel')                  -> NS/turtle1/cmd_vel
//   a name NS has ('/turtle1/cmd_vel' and NS/turtle1/cmd_vel exists) -> NS/turtle1/cmd_vel
//   a name the gateway has as it is ('/add_two_ints', '/s03/turtle1/pose', '/s07/...') -> as it is
//   any other name (a new topic)                          -> NS/...
// With no namespace a relative name is under '/' and every other name is as it is.
// `has(kind, name)`: whether the live graph has that topic, service or action.
export function inRobotNamespace(ns, kind, name, has = () => false) {
  name = String(name ?? '');
  if (!name.startsWith('/')) return true;
  if (!ns || name === ns || name.startsWith(`${ns}/`)) return false;
  if (has(kind, `${ns}${name}`)) return true;
  return !has(kind, name);
}

// The scope a generator writes names in: ns() is the page's robot namespace, has(kind, name) asks
// its live graph, types(kind, type) gives the rosapi typedefs the page has read of a type (the ROS 2
// node's typed messages), or undefined (see main.js). Without a page: no namespace, no graph.
export class NameScope {
  constructor({ ns = () => '', has = () => false, types = () => undefined } = {}) {
    this.ns = ns;
    this.has = has;
    this.types = types;
  }

  inNamespace(kind, name) { return inRobotNamespace(this.ns(), kind, name, this.has); }
}

// The name fields of the generic ROS blocks and what they name.
export const NAME_KINDS = { TOPIC: 'topic', SERVICE: 'service', ACTION: 'action' };

// "send feedback" speaks for the goal of the 'serve action' block it is in (none outside one).
export function inServeAction(block) {
  for (let b = block.getSurroundParent(); b; b = b.getSurroundParent()) if (b.type === 'ros_serve_action') return true;
  return false;
}
