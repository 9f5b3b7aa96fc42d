// Running the program: the block runner, the text runner with its editor (js/editors/textmode.js,
// js/run/textrun.js), runs on the robot, the teacher's report, and Run, Pause, Step, Stop. A program
// drives only this person's robot, and not while the teacher's stop holds.
import { Runner } from '../run/runner.js';
import { TextRunner } from '../run/textrun.js';
import { TextMode } from '../editors/textmode.js';
import { RobotRuns } from '../lab/robotruns.js';
import { reportProgram } from './report.js';
import { guard as foreignGuard } from '../run/foreign.js';
import { t } from '../i18n.js';

const $ = (sel) => document.querySelector(sel);

export function mountRunning(ide) {
  const { workspace, graph, lease, robotNs, link, console: consoleView } = ide;
  const runner = new Runner(workspace, () => ide.ros, consoleView, () => ide.ns,
    { ready: () => graph.ready(), loose: ide.looseBlocks });
  ide.runner = runner;
  const textRunner = new TextRunner(ide, { ready: () => graph.ready() });
  ide.textRunner = textRunner;
  const textMode = new TextMode(ide, { changed: () => { ide.changed(); ide.report?.edited(); } });
  ide.textMode = textMode;
  ide.robotRuns = new RobotRuns(ide);
  ide.robotRuns.init();
  const runState = () => { document.body.dataset.run = textRunner.state !== 'idle' ? textRunner.state : runner.state; };
  runner.addEventListener('state', runState);
  textRunner.addEventListener('state', runState);
  lease.addEventListener('stop', () => {
    runner.stop();
    textRunner.stop(t('text.why.teacher'));
    consoleView.warn(t('ide.stopped.teacher', { robot: ide.ns || t('ide.this.robot') }));
  });
  ide.report = reportProgram(ide, { workspace, runners: [runner, textRunner], consoleEl: $('#console-lines') });
  $('#take').addEventListener('click', () => ide.report.clear());   // her Take: the tile's error is behind her
  document.body.dataset.run = 'idle';
  // a program drives only this person's robot, and not while the teacher's stop holds: said here
  // once per press, not as an error of the program's blocks
  const mayDrive = () => { const why = robotNs.whyNot(); if (why) consoleView.warn(why); return !why; };
  // a program from another person's link runs once its opener says so, without her admin rights
  ide.mayRun = foreignGuard(ide, {
    reconnect: () => new Promise((resolve) => { link.addEventListener('open', () => resolve(), { once: true }); link.restart(); }),
  });
  $('#run').onclick = async () => {
    if (!mayDrive() || !(await ide.mayRun())) return;
    if (textMode.active) textRunner.run(textMode.text, textMode.lang);
    else if (runner.state === 'paused') runner.resume();
    else runner.run();
  };
  $('#pause').onclick = () => runner.pause();
  $('#step').onclick = async () => mayDrive() && (await ide.mayRun()) && runner.step();
  $('#stop').onclick = () => { runner.stop(); textRunner.stop(t('text.why.button')); };
}
