// The nodes of the graph (in the robot's namespace, or all) and, for the one chosen, what it
// publishes, subscribes to, serves (its parameter services aside: its parameters are shown below)
// and which actions it serves — from rosapi (nodes, node_details, action_servers, and the node
// behind each action's hidden send_goal service, which ROS 2 names after the action).
import { t, num } from '../i18n.js';

const PARAM_SERVICES = ['describe_parameters', 'get_parameter_types', 'get_parameters', 'list_parameters',
  'set_parameters', 'set_parameters_atomically', 'get_type_description'];

export const isParamService = (node, name) => PARAM_SERVICES.some((s) => name === `${node}/${s}`);

// {action name -> node} of the graph's actions
export async function actionNodes(wire) {
  const { action_servers: actions } = await wire.call('/rosapi/action_servers');
  const found = await Promise.all(actions.map((a) => wire.call('/rosapi/service_node', { service: `${a}/_action/send_goal` })
    .then((r) => [a, r.node], () => [a, ''])));
  return new Map(found);
}

export class Nodes extends EventTarget {
  constructor(wire, els) {
    super();
    this.wire = wire;
    this.els = els;     // {root, list, details, title, filter, count}
    this.ns = '';
    this.nodes = [];
    this.chosen = '';
    els.filter?.addEventListener('input', () => this.render());
  }

  setNamespace(ns) { this.ns = ns; this.render(); }

  async refresh() {
    try {
      this.nodes = (await this.wire.call('/rosapi/nodes')).nodes;
    } catch { return; }
    this.render();
  }

  render() {
    const text = this.els.filter?.value.trim().toLowerCase() ?? '';
    const shown = this.nodes.filter((n) => (!this.ns || n.startsWith(`${this.ns}/`)) && (!text || n.toLowerCase().includes(text)));
    this.els.list.replaceChildren(...shown.map((n) => {
      const li = document.createElement('li');
      const b = document.createElement('button');
      b.type = 'button';
      b.textContent = n;
      b.dataset.node = n;
      b.toggleAttribute('aria-current', n === this.chosen);
      b.addEventListener('click', () => this.choose(n));
      li.append(b);
      return li;
    }));
    this.els.count.textContent = t('inspect.nodes.count', { n: num(shown.length) });
    this.els.root.dataset.nodes = String(shown.length);
  }

  async choose(node) {
    this.chosen = node;
    for (const b of this.els.list.querySelectorAll('button')) b.toggleAttribute('aria-current', b.dataset.node === node);
    this.els.title.textContent = node;
    let details;
    let actions = new Map();
    try {
      [details, actions] = await Promise.all([this.wire.call('/rosapi/node_details', { node }), actionNodes(this.wire).catch(() => new Map())]);
    } catch (e) {
      this.els.details.textContent = t('inspect.failed', { error: e.message });
      return;
    }
    if (node !== this.chosen) return;
    const served = [...actions].filter(([, n]) => n === node).map(([a]) => a);
    const services = details.services.filter((s) => !isParamService(node, s));
    const section = (key, names, kind) => {
      const div = document.createElement('div');
      div.className = 'group';
      div.dataset.kind = kind;
      const h = document.createElement('h3');
      h.textContent = t(key, { n: num(names.length) });
      const ul = document.createElement('ul');
      ul.append(...names.map((name) => {
        const li = document.createElement('li');
        li.textContent = name;
        if (kind === 'publishing' || kind === 'subscribing') {
          li.tabIndex = 0;
          li.classList.add('topic');
          li.addEventListener('click', () => this.dispatchEvent(new CustomEvent('topic', { detail: name })));
        }
        return li;
      }));
      div.append(h, ul);
      return div;
    };
    this.els.details.replaceChildren(section('inspect.node.publishes', details.publishing, 'publishing'),
      section('inspect.node.subscribes', details.subscribing, 'subscribing'),
      section('inspect.node.services', services, 'services'), section('inspect.node.actions', served, 'actions'));
    this.els.root.dataset.chosen = node;
    this.dispatchEvent(new CustomEvent('node', { detail: { node, services: details.services } }));
  }
}
