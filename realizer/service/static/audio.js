// Speech audio in the browser viewer: the viewer protocol's `audio` messages (PCM16 chunks
// stamped on the server clock, protocols/viewer.md) played through Web Audio, each chunk
// scheduled at its server time mapped onto the AudioContext's clock, so sound and picture
// (frames are drawn as they arrive, stamped with the same clock) stay together. A chunk that
// arrives late starts part-way through, at the sample that is due now, instead of drifting.

export class AudioPlayer {
  constructor() {
    const Context = window.AudioContext || window.webkitAudioContext;
    this.context = Context ? new Context() : null;
    this.scheduled = [];  // {character, start (server s), at (context s), duration}
    this.played = 0;      // chunks scheduled
    this.skipped = 0;     // chunks that came after their end
    this.sources = new Set();
  }
  async resume() { if (this.context && this.context.state !== "running") await this.context.resume(); }
  // m: {t: server seconds of the first sample, rate: samples per second, pcm: bin int16 LE}
  push(character, m, serverNow) {
    if (!this.context || !m.pcm || !m.rate) return;
    const samples = new Int16Array(m.pcm.slice().buffer);
    const rate = m.rate, duration = samples.length / rate;
    const lateBy = serverNow - m.t;  // seconds of this chunk already due
    if (lateBy >= duration) { this.skipped++; return; }
    const skip = Math.max(0, Math.floor(lateBy * rate));
    const buffer = this.context.createBuffer(1, samples.length - skip, rate);
    const channel = buffer.getChannelData(0);
    for (let i = skip; i < samples.length; i++) channel[i - skip] = samples[i] / 32768;
    const source = this.context.createBufferSource();
    source.buffer = buffer;
    source.connect(this.context.destination);
    const at = this.context.currentTime + Math.max(0, -lateBy);
    source.start(at);
    this.sources.add(source);
    source.onended = () => this.sources.delete(source);
    this.scheduled.push({ character, start: m.t, at, duration, skip: skip / rate });
    if (this.scheduled.length > 200) this.scheduled.shift();
    this.played++;
  }
  // Stop every scheduled chunk (an interrupted speech's audio is cut by the server; this
  // is for switching characters).
  stop() { for (const s of this.sources) { try { s.stop(); } catch (e) { /* already ended */ } } }
}
