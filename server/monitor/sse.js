// Server-Sent Events as the monitor reads them (fetch() and a stream reader, since EventSource cannot send the
// bearer header): text in, split anywhere, whole events out. Comments and unknown fields are skipped; several data
// lines join with "\n"; CR LF and CR end lines as LF does. As in the SSE standard, an id holds for the events after
// it until another id comes.
export class SseParser {
  /** onEvent({id, type, data}) is called for every complete event that has data. */
  constructor(onEvent) {
    this.onEvent = onEvent;
    this.buffer = '';
    this.id = '';
    this.reset();
  }

  reset() {
    this.type = '';
    this.data = [];
  }

  /** Consumes a piece of the stream's text. */
  feed(text) {
    this.buffer += text;
    // A CR at the very end may be half of a CR LF: keep it until the next piece.
    let cut = this.buffer.length;
    if (this.buffer.endsWith('\r')) cut -= 1;
    const lines = this.buffer.slice(0, cut).split(/\r\n|\r|\n/);
    this.buffer = lines.pop() + this.buffer.slice(cut);
    for (const line of lines) this.line(line);
  }

  line(line) {
    if (line === '') {
      if (this.data.length) this.onEvent({ id: this.id, type: this.type || 'message', data: this.data.join('\n') });
      this.reset();
      return;
    }
    if (line.startsWith(':')) return;
    const colon = line.indexOf(':');
    const field = colon < 0 ? line : line.slice(0, colon);
    const value = colon < 0 ? '' : line.slice(colon + 1).replace(/^ /, '');
    if (field === 'id') this.id = value;
    else if (field === 'event') this.type = value;
    else if (field === 'data') this.data.push(value);
  }
}
