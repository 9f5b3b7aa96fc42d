// Publish a message and call a service from forms built from their types (form.js): the topic's
// type from the graph (or typed, for a new topic), the service's from rosapi. Both go through the
// gateway's rules as any client's op: the driver lease, the roles, the name globs, the velocity
// clamps; a refusal is shown as the gateway words it. A service's response is shown as a tree.
import { MessageForm, FormError } from './form.js';
import { Tree } from './tree.js';
import { t } from '../i18n.js';

export class Sender {
  constructor(wire, els) {
    this.wire = wire;
    this.els = els;   // {pub: {root, topic, type, form, send, info}, call: {root, service, form, send, info, result}}
    this.pubForm = null;
    this.callForm = null;
    this.callType = '';
    this.types = new Map();
    this.result = new Tree(els.call.result);
    // (a field's change event comes again on leaving it: the same name keeps the form as filled)
    els.pub.topic.addEventListener('change', () => this.choosePublish(els.pub.topic.value.trim()));
    els.pub.type.addEventListener('change', () => this.buildPublish(els.pub.type.value.trim()));
    els.pub.send.addEventListener('click', () => this.publish());
    els.call.service.addEventListener('change', () => this.chooseService(els.call.service.value.trim()));
    els.call.send.addEventListener('click', () => this.call());
  }

  setTopics(types) { this.types = types; }

  async choosePublish(topic, type = this.types.get(topic)) {
    this.els.pub.topic.value = topic;
    if (type) this.els.pub.type.value = type;
    await this.buildPublish(this.els.pub.type.value.trim());
  }

  async buildPublish(type) {
    const p = this.els.pub;
    if (type && type === p.root.dataset.ready && this.pubForm) return;
    p.root.dataset.ready = '';
    if (!type) return;
    try {
      const { typedefs } = await this.wire.call('/rosapi/message_details', { type });
      this.pubForm = new MessageForm(p.form, typedefs);
      p.info.textContent = '';
      p.root.dataset.ready = type;
    } catch (e) {
      p.form.replaceChildren();
      this.pubForm = null;
      p.info.textContent = t('inspect.failed', { error: e.message });
    }
  }

  async publish() {
    const p = this.els.pub;
    if (!this.pubForm) return;
    const topic = p.topic.value.trim();
    p.root.dataset.result = '';
    try {
      await this.wire.publish(topic, p.type.value.trim(), this.pubForm.value());
      p.info.textContent = t('inspect.send.published', { topic });
      p.root.dataset.result = 'published';
    } catch (e) {
      p.info.textContent = e instanceof FormError ? e.message : t('inspect.refused', { why: e.message });
      p.root.dataset.result = 'refused';
    }
  }

  async chooseService(service) {
    const c = this.els.call;
    if (service && service === this.callService && c.root.dataset.ready) return;
    this.callService = service;
    c.service.value = service;
    c.root.dataset.ready = '';
    c.result.replaceChildren();
    try {
      const { type } = await this.wire.call('/rosapi/service_type', { service });
      if (!type) throw new Error(t('inspect.send.no.service', { service }));
      const { typedefs } = await this.wire.call('/rosapi/service_request_details', { type });
      this.callType = type;
      this.callForm = typedefs.length ? new MessageForm(c.form, typedefs) : null;
      if (!typedefs.length) c.form.replaceChildren();
      c.info.textContent = type;
      c.root.dataset.ready = type;
    } catch (e) {
      this.callForm = null;
      c.form.replaceChildren();
      c.info.textContent = t('inspect.failed', { error: e.message });
    }
  }

  async call() {
    const c = this.els.call;
    const service = c.service.value.trim();
    if (!service || !c.root.dataset.ready) return;
    c.root.dataset.result = '';
    try {
      const values = await this.wire.call(service, this.callForm ? this.callForm.value() : {}, { type: this.callType });
      this.result.show(values);
      c.info.textContent = t('inspect.send.answered', { service });
      c.root.dataset.result = 'answered';
    } catch (e) {
      c.info.textContent = e instanceof FormError ? e.message : t('inspect.refused', { why: e.message });
      c.root.dataset.result = 'refused';
    }
  }
}
