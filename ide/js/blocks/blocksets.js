// Block sets the gateway serves from its --blocks-dir (GET api/blocks): a robot's own blocks,
// written as a JSON file in the form of ide/blocks/*.json with a "robot" glob of namespaces, listed
// in the toolbox for the robots it names, with no change to the IDE's code; and the class's shared
// blocks, made with "make a block" and published by an admin (POST api/blocks/shared). A shared
// block a program uses is saved with the program, as the person's own made blocks are, so the
// program opens where the library is not.
import { t } from '../i18n.js';
import { nameGlob } from '../robot/graph.js';
import { madeProblem, setProblem } from './blockcheck.js';
import { api, ApiError } from '../link/api.js';

/** A set's robot glob (`/husky*`, `/`, `*`) against a robot namespace ('' : the one robot, '/'). */
export function robotMatches(glob, ns) {
  return !glob || glob === '*' || nameGlob(glob).test(ns || '/');
}

export class BlockSets {
  constructor() {
    this.sets = [];
    this.shared = [];      // [{json, spec, toolboxInputs}], as makeblock.js builds them
    this.publishable = false;
  }

  /** Reads the gateway's sets and defines their blocks with define(def, colour, namespaced). */
  async load(define) {
    let body;
    try { body = await api('api/blocks'); } catch { return; }   // a gateway without the route: the IDE's own sets alone
    if (!body) return;
    // data, checked as the gateway checked them (js/blocks/blockcheck.js): one that is not is left out
    this.sets = (body.sets ?? []).filter((set) => {
      const why = setProblem(set, set.file);
      if (why) console.warn(why);
      return !why;
    });
    this.shared = (body.shared ?? []).filter((made) => {
      const why = madeProblem(made, 'shared');
      if (why) console.warn(why);
      return !why;
    });
    this.publishable = !!body.publish;
    for (const set of this.sets) {
      for (const def of set.blocks) {
        try { define(def, set.colour, set.namespaced); } catch (e) { console.warn(set.file, e);   /* the developer's console: which set, and why */ }
      }
    }
    for (const made of this.shared) {
      try { define({ ...made.json, rosgate: made.spec }, 330, false, { made: true }); } catch (e) { console.warn(e); }
    }
  }

  /** The toolbox categories for the robot in namespace ns; entries(set) gives a set's blocks. */
  categories(ns, entries) {
    const out = this.sets.filter((s) => robotMatches(s.robot, ns)).map((set) => ({
      kind: 'category', name: set.name, colour: String(set.colour), contents: entries(set),
    }));
    if (this.shared.length) {
      out.push({ kind: 'category', name: t('ide.blocks.shared'), colour: '300',
        contents: this.shared.map((m) => ({ kind: 'block', type: m.json.type, inputs: m.toolboxInputs ?? {} })) });
    }
    return out;
  }

  sharedOf(type) { return this.shared.find((m) => m.json.type === type); }

  /** Publishes made blocks to the class's library; resolves to how many, rejects with the gateway's word. */
  async publish(made) {
    for (const m of made) {
      try { await api('api/blocks/shared', { method: 'POST', body: m }); } catch (e) {
        if (e instanceof ApiError && !e.body?.error) e.message = `${e.status}`;   // the gateway's word, else the status
        throw e;
      }
      if (!this.sharedOf(m.json.type)) this.shared.push(m);
    }
    return made.length;
  }
}
