// The echo of one topic: its newest message as a folding tree (tree.js), at most as often as the
// rate chosen (subscribe's throttle_rate, queue_length 1: the gateway drops what the page would
// not show), pausable (paused, the page unsubscribes and keeps the last message). An image topic
// (sensor_msgs Image or CompressedImage) is shown as the picture, made to measure by the gateway
// (subscribe's `image` field: a JPEG at most WIDTH wide, whatever the camera sends).
import { Tree } from './tree.js';
import { t, num, time } from '../i18n.js';

export const IMAGE_TYPES = ['sensor_msgs/msg/Image', 'sensor_msgs/msg/CompressedImage'];
const WIDTH = 480;

export class Echo {
  constructor(wire, els) {
    this.wire = wire;
    this.els = els;          // {topic, rate, pause, info, tree, image}
    this.tree = new Tree(els.tree);
    this.topic = '';
    this.type = '';
    this.sub = null;
    this.paused = false;
    this.count = 0;
    this.last = null;
    els.pause.addEventListener('click', () => this.pause(!this.paused));
    els.rate.addEventListener('change', () => this._resubscribe());
    els.topic.addEventListener('change', () => this.show(els.topic.value.trim(), this.types?.get(els.topic.value.trim()) ?? ''));
  }

  // topic -> type of the graph (for the topic field's choices)
  setTopics(types) { this.types = types; }

  async show(topic, type) {
    this.sub?.close();   // at once: a message of the topic shown before must not land under this one
    this.sub = null;
    this.topic = topic;
    this.type = type;
    this.els.topic.value = topic;
    this.count = 0;
    this.last = null;
    this.els.tree.replaceChildren();
    this.els.image.hidden = true;
    this.els.image.removeAttribute('src');
    this.els.info.textContent = topic ? t('inspect.echo.waiting') : '';
    this.els.root.dataset.topic = topic;
    this.els.root.dataset.count = '0';
    if (type && !IMAGE_TYPES.includes(type)) {
      let typedefs = null;
      try { typedefs = (await this.wire.call('/rosapi/message_details', { type })).typedefs; } catch { /* shown as it comes */ }
      if (topic !== this.topic) return;   // another was chosen meanwhile
      if (typedefs) this.tree.setTypedefs(typedefs);
    }
    this._resubscribe();
  }

  pause(on) {
    this.paused = on;
    this.els.pause.setAttribute('aria-pressed', String(on));
    this.els.pause.textContent = t(on ? 'inspect.echo.resume' : 'inspect.echo.pause');
    this.els.root.dataset.paused = String(on);
    this._resubscribe();
  }

  _resubscribe() {
    this.sub?.close();
    this.sub = null;
    if (!this.topic || this.paused) return;
    const image = IMAGE_TYPES.includes(this.type);
    const options = { throttle_rate: Number(this.els.rate.value), queue_length: 1 };
    if (image) options.image = { width: WIDTH, quality: 70 };
    const sub = this.wire.subscribe(this.topic, this.type || undefined, (msg) => { if (this.sub === sub) this._message(msg, image); },
      options, (why) => { this.els.info.textContent = t('inspect.refused', { why }); });
    this.sub = sub;
  }

  _message(msg, image) {
    this.count += 1;
    this.last = msg;
    this.els.root.dataset.count = String(this.count);
    const stamp = msg.header?.stamp;
    const when = stamp?.sec ? time(stamp.sec * 1000 + (stamp.nanosec ?? 0) / 1e6) : time(Date.now());
    this.els.info.textContent = t('inspect.echo.info', { n: num(this.count), time: when });
    if (image && msg.data !== undefined) {
      const data = typeof msg.data === 'string' ? msg.data : btoa(String.fromCharCode(...msg.data));
      this.els.image.src = `data:image/jpeg;base64,${data}`;
      this.els.image.hidden = false;
      this.tree.show({ header: msg.header, format: msg.format });
      return;
    }
    this.tree.show(msg);
  }
}
