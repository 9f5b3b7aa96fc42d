// Every camera the robot has, on the teleop page: the image topics of its namespace (Image, or
// CompressedImage named as image_transport names it, `BASE/compressed`), beside the main camera
// card. A picker chooses which are shown; they sit side by side on a tablet, one under the other
// on a phone. Each comes made to measure over the page's connection (the ``image`` field of
// subscribe: at most 320 px wide at quality 60, ~8 KB a frame, its aspect kept, encoded once per
// size for every viewer; 5 frames a second, the newest only), and its caption links
// web_video_server's viewer page (/stream_viewer) at full size; an unchecked camera is unsubscribed.
import { t } from '../i18n.js';

const IMAGE_TYPES = /^sensor_msgs\/(msg\/)?(Image|CompressedImage)$/;
const KEY = 'rosgate.cameras.hidden';
const MAX_SHOWN = 4;   // cameras shown at first (more are in the picker, unchecked)

// The cameras among topics/types of a namespace ('' : all): base topic -> {topic, type} to
// subscribe (the raw Image when there is one, else BASE/compressed).
export function cameraTopics(topics, types, ns) {
  const out = new Map();
  topics.forEach((topic, i) => {
    if (!IMAGE_TYPES.test(types[i] ?? '') || (ns && !topic.startsWith(`${ns}/`))) return;
    const base = /CompressedImage$/.test(types[i]) ? topic.replace(/\/compressed$/, '') : topic;
    if (!out.has(base) || base === topic) out.set(base, { topic: topic, type: types[i] });
  });
  return new Map([...out].sort(([a], [b]) => a.localeCompare(b)));
}

const live = new Map();   // base topic -> {ros, topic, id, listener}: what is subscribed now
let seq = 0;

function open(ros, base, { topic, type }, img) {
  const id = `subscribe:${topic}:cameras.${++seq}`;
  const listener = (m) => {
    const data = m.msg.data;
    img.src = `data:image/jpeg;base64,${typeof data === 'string' ? data : btoa(String.fromCharCode(...data))}`;
  };
  ros.on(topic, listener);
  ros.callOnConnection({ op: 'subscribe', id, topic, type, throttle_rate: 200, queue_length: 1,
    image: { width: 320, quality: 60 } });
  live.set(base, { ros, topic, id, listener });
}

function close(base) {
  const s = live.get(base);
  if (!s) return;
  s.ros.off(s.topic, s.listener);
  s.ros.callOnConnection({ op: 'unsubscribe', id: s.id, topic: s.topic });
  live.delete(base);
}

function hiddenSet() {
  try { return new Set(JSON.parse(localStorage.getItem(KEY) ?? '[]')); } catch { return new Set(); }
}

function viewerUrl(topic) {
  return `stream_viewer?${new URLSearchParams({ topic }).toString().replace(/%2F/gi, '/')}`;
}

/**
 * Shows the robot's other cameras in a card after `after` (the main camera's card); main: the
 * main camera's topic (left out here). Returns the card (hidden when there are none).
 */
export function showCameras({ ros, topics, types, ns, main, after }) {
  const mainBase = String(main ?? '').replace(/\/compressed$/, '');
  const found = cameraTopics(topics, types, ns);
  found.delete(mainBase);
  const cameras = [...found.keys()];
  let card = document.querySelector('#cameras-card');
  if (!card) {
    card = document.createElement('section');
    card.id = 'cameras-card';
    card.className = 'card';
    const h2 = document.createElement('h2');
    h2.textContent = t('cameras.title');
    const pick = document.createElement('div');
    pick.className = 'camera-picker';
    pick.setAttribute('role', 'group');
    pick.setAttribute('aria-label', t('cameras.shown'));
    const gridEl = document.createElement('div');
    gridEl.className = 'camera-grid';
    card.append(h2, pick, gridEl);
    after.after(card);
  }
  card.hidden = !cameras.length;
  const hidden = hiddenSet();
  const picker = card.querySelector('.camera-picker'), grid = card.querySelector('.camera-grid');
  const shown = (topic, i) => !hidden.has(topic) && i < MAX_SHOWN;
  const draw = () => {
    const want = cameras.filter((topic, i) => picker.querySelector(`input[value="${CSS.escape(topic)}"]`)?.checked ?? shown(topic, i));
    for (const fig of [...grid.children]) {
      const topic = fig.dataset.topic;
      if (!want.includes(topic) || live.get(topic)?.ros !== ros) { close(topic); fig.remove(); }
    }
    for (const topic of want) {
      if (grid.querySelector(`figure[data-topic="${CSS.escape(topic)}"]`)) continue;
      const fig = document.createElement('figure');
      fig.dataset.topic = topic;
      const img = document.createElement('img');
      img.alt = t('cameras.alt', { topic });
      const cap = document.createElement('figcaption');
      const link = document.createElement('a');
      link.href = viewerUrl(topic);
      link.target = '_blank';
      link.textContent = topic;
      cap.append(link);
      fig.append(img, cap);
      grid.append(fig);
      open(ros, topic, found.get(topic), img);
    }
  };
  picker.replaceChildren(...cameras.map((topic, i) => {
    const label = document.createElement('label');
    const box = document.createElement('input');
    box.type = 'checkbox';
    box.value = topic;
    box.checked = shown(topic, i);
    box.addEventListener('change', () => {
      const now = hiddenSet();
      if (box.checked) now.delete(topic); else now.add(topic);
      try { localStorage.setItem(KEY, JSON.stringify([...now])); } catch { /* storage off */ }
      draw();
    });
    label.append(box, ` ${topic}`);
    return label;
  }));
  draw();
  return card;
}
