// Speech audio in the browser viewer: the viewer protocol's `audio` messages (PCM16 chunks
// stamped on the server clock, protocols/viewer.md) played through Web Audio. The server
// clock (the viewer's estimate from the frames' `t` and their arrival times, `serverNow`) is
// mapped onto the AudioContext's clock, each chunk starts at its `t` on that mapping, and a
// chunk that joins the previous one sample for sample starts exactly where it ended, so
// speech has no clicks and keeps the frames' clock. `audioCut` stops what was scheduled at
// or after its `t`.

export class AudioPlayer {
  constructor() {
    const Context = window.AudioContext || window.webkitAudioContext;
    this.context = Context ? new Context({ latencyHint: "interactive" }) : null;
    this.offset = null;  // context seconds minus server seconds
    this.scheduled = [];  // {character, t, at, duration, source}
    this.played = 0;      // chunks scheduled
    this.skipped = 0;     // chunks that came after their end
    this.cuts = 0;
    this.next = new Map();  // character -> {sample, at}: where its stream continues
  }
  async resume() { if (this.context && this.context.state !== "running") await this.context.resume(); }
  // The output's delay: a sample scheduled at context time x is heard at x + latency.
  latency() {
    const c = this.context;
    return (c.baseLatency || 0) + (c.outputLatency || 0);
  }
  // m: {t: server seconds of the first sample, rate, samples: bin int16 LE}; serverNow: the
  // viewer's estimate of the server clock now (seconds).
  push(character, m, serverNow) {
    const pcm = m.samples || m.pcm;
    if (!this.context || !pcm || !m.rate || this.context.state !== "running") return;
    const samples = new Int16Array(pcm.slice().buffer);
    const rate = m.rate, first = Math.round(m.t * rate);
    this.offset = this.context.currentTime - serverNow;  // the clocks' mapping now
    const continued = this.next.get(character);
    let at = continued && continued.sample === first ? continued.at : m.t + this.offset - this.latency();
    let skip = 0;
    const now = this.context.currentTime;
    if (at < now) {  // late: start at the sample that is due now
      skip = Math.ceil((now - at) * rate);
      if (skip >= samples.length) { this.skipped++; this.next.delete(character); return; }
      at += skip / rate;
    }
    const buffer = this.context.createBuffer(1, samples.length - skip, rate);
    const channel = buffer.getChannelData(0);
    for (let i = skip; i < samples.length; i++) channel[i - skip] = samples[i] / 32768;
    const source = this.context.createBufferSource();
    source.buffer = buffer;
    source.connect(this.context.destination);
    source.start(at);
    const duration = buffer.duration;
    this.next.set(character, { sample: first + samples.length, at: at + duration });
    const entry = { character, t: m.t + skip / rate, at, duration, source };
    this.scheduled.push(entry);
    source.onended = () => { entry.ended = true; };
    if (this.scheduled.length > 400) this.scheduled.shift();
    this.played++;
  }
  // Stop every sample of `character` scheduled at or after server time t.
  cut(character, t) {
    if (!this.context || this.offset === null) return;
    for (const e of this.scheduled) {
      if (e.character !== character || e.ended) continue;
      const stopAt = e.at + Math.max(0, t - e.t);
      if (stopAt < e.at + e.duration) {
        try { e.source.stop(Math.max(stopAt, this.context.currentTime)); } catch (err) { /* ended */ }
        e.duration = Math.max(0, stopAt - e.at);
      }
    }
    this.next.delete(character);
    this.cuts++;
  }
  // When (performance.now() milliseconds) the sample of server time t is heard, or null.
  heardAt(t) {
    if (!this.context || this.offset === null || !this.context.getOutputTimestamp) return null;
    const e = this.scheduled.find((x) => x.t <= t && t < x.t + x.duration);
    if (!e) return null;
    // the output timestamp pairs the sample being heard now with its performance time
    const stamp = this.context.getOutputTimestamp();
    return stamp.performanceTime + (e.at + (t - e.t) - stamp.contextTime) * 1000;
  }
  stop() {
    for (const e of this.scheduled) { try { e.source.stop(); } catch (err) { /* ended */ } }
    this.next.clear();
  }
}
