//! Reading a recording's messages: the data section walked a record at a time,
//! a chunk decompressed as it is reached, messages decoded with the contract's
//! types; and the duration, from the newest surface frame.

use super::*;

impl Recording {
    /// Simulated time of the last tick recorded, s (0 without any): the newest
    /// surface frame's, as [`crate::recording::summarize`] counts the duration. Frames are
    /// written in tick order, so it is in the newest chunk holding one: an indexed
    /// file (every file the recorder finishes or recovery writes) says which; in
    /// another the newest chunks are opened one at a time, at most
    /// [`MAX_DURATION_CHUNKS`] of them. A chunk that does not read is an error in a
    /// finished file, and skipped in an unfinished one (its session may be writing
    /// over it).
    pub fn duration_s(&self) -> Result<f64, ReadError> {
        let mut topics = topics(&self.summary);
        let mut unknown = 0;
        for chunk in self.chunks.iter().rev() {
            match chunk.surface {
                Some(false) => continue,
                Some(true) => {}
                None if unknown == MAX_DURATION_CHUNKS => break,
                None => unknown += 1,
            }
            let records = match self.chunk_at(chunk.at) {
                Ok(r) => r,
                Err(e) if self.complete => return Err(e),
                Err(_) => continue,
            };
            let frames = records.into_iter().filter_map(|r| match r {
                Record::Channel(c) => {
                    topics.insert(c.id, c.topic);
                    None
                }
                Record::Message { header, data }
                    if topics.get(&header.channel_id).map(String::as_str)
                        == Some(TOPIC_SURFACE) =>
                {
                    Some(Ok((header, data.into_owned())))
                }
                _ => None,
            });
            let mut any = false;
            let t = self.latest_frame_time(frames.inspect(|_| any = true))?;
            if any {
                return Ok(t);
            }
        }
        Ok(0.0)
    }

    /// The records of the chunk whose record starts at `at`.
    fn chunk_at(&self, at: u64) -> Result<Vec<Record<'static>>, ReadError> {
        let framed = frame_at(&self.source, at, self.data_end)
            .map_err(|e| self.corrupt(e.to_string()))?
            .ok_or_else(|| self.corrupt(format!("an index points at byte {at}, past its data")))?;
        match read_record(&self.source, &framed).map_err(|e| self.corrupt(e))? {
            Record::Chunk { header, data } => {
                chunk_records(&header, &data).map_err(|e| self.corrupt(e))
            }
            _ => Err(self.corrupt(format!(
                "its chunk index points at byte {at}, where no chunk starts"
            ))),
        }
    }

    /// The largest simulated time of the surface frames given undecoded.
    fn latest_frame_time(
        &self,
        frames: impl Iterator<Item = Result<(MessageHeader, Vec<u8>), ReadError>>,
    ) -> Result<f64, ReadError> {
        let mut t: f64 = 0.0;
        for f in frames {
            let (header, data) = f?;
            let frame: v1::SurfaceFrame = self.decode(TOPIC_SURFACE, &header, &data)?;
            t = t.max(frame.sim_time_s);
        }
        Ok(t)
    }

    /// The file's MCAP summary (channels, schemas, statistics, indexes).
    pub fn mcap_summary(&self) -> &Summary {
        &self.summary
    }

    /// Messages per topic, from the file's statistics; a file without them (an
    /// unfinished one) is read through, a chunk at a time, and counted up to its
    /// first error.
    pub fn message_counts(&self) -> BTreeMap<String, u64> {
        let mut counts = BTreeMap::new();
        if self.summary.stats.is_none() {
            for m in self.raw() {
                let Ok((topic, _, _)) = m else { break };
                *counts.entry(topic).or_default() += 1;
            }
        }
        if let Some(stats) = &self.summary.stats {
            for (id, n) in &stats.channel_message_counts {
                if let Some(c) = self.summary.channels.get(id) {
                    *counts.entry(c.topic.clone()).or_default() += n;
                }
            }
        }
        counts
    }

    /// Every message of the contract's topics in file order, decoded. Messages of
    /// other topics (`/foxglove/scene`, for viewers, and any this version does not
    /// know) are skipped undecoded; reading ends at the first error.
    pub fn messages(&self) -> impl Iterator<Item = Result<Stamped<Recorded>, ReadError>> + '_ {
        Self::messages_of(self)
    }

    /// [`messages`](Self::messages) owning the recording: an iterator that can be
    /// kept between reads (a replay reads in bursts, moving it to a blocking thread
    /// for each).
    pub fn into_messages(
        self: std::sync::Arc<Self>,
    ) -> impl Iterator<Item = Result<Stamped<Recorded>, ReadError>> + Send + 'static {
        Self::messages_of(self)
    }

    fn messages_of<R: std::ops::Deref<Target = Recording> + Clone>(
        this: R,
    ) -> impl Iterator<Item = Result<Stamped<Recorded>, ReadError>> {
        let decoder = this.clone();
        Self::raw_of(this).filter_map(move |m| {
            let (topic, header, data) = match m {
                Ok(m) => m,
                Err(e) => return Some(Err(e)),
            };
            let d = &*decoder;
            let decoded = match topic.as_str() {
                TOPIC_SCENE => d.decode(&topic, &header, &data).map(Recorded::Scene),
                TOPIC_POSES => d.decode(&topic, &header, &data).map(Recorded::Pose),
                TOPIC_SURFACE => d.decode(&topic, &header, &data).map(Recorded::Surface),
                TOPIC_INSTRUMENTS => d.decode(&topic, &header, &data).map(Recorded::Instrument),
                TOPIC_EVENTS => d.decode(&topic, &header, &data).map(Recorded::Event),
                _ => return None,
            };
            Some(decoded.map(|message| Stamped {
                log_time: header.log_time,
                publish_time: header.publish_time,
                message,
            }))
        })
    }

    /// The messages of one topic, decoded as `T`, in file order.
    pub fn topic<T: prost::Message + Default>(
        &self,
        topic: &str,
    ) -> Result<Vec<Stamped<T>>, ReadError> {
        let mut out = Vec::new();
        for m in self.raw() {
            let (t, header, data) = m?;
            if t == topic {
                out.push(Stamped {
                    log_time: header.log_time,
                    publish_time: header.publish_time,
                    message: self.decode(&t, &header, &data)?,
                });
            }
        }
        Ok(out)
    }

    /// Every message in file order, undecoded, with its topic: the data section
    /// walked a record at a time, each chunk read and decompressed as it is reached
    /// (one in memory at a time), indexes and other records skipped unread. A
    /// record that does not fit in the file as it is now (cut or rewritten while
    /// read) ends the messages with an error, as a damaged one does.
    fn raw(
        &self,
    ) -> impl Iterator<Item = Result<(String, MessageHeader, Vec<u8>), ReadError>> + '_ {
        Self::raw_of(self)
    }

    /// [`raw`](Self::raw) of a recording held by `this` (a reference or an `Arc`).
    fn raw_of<R: std::ops::Deref<Target = Recording>>(
        this: R,
    ) -> impl Iterator<Item = Result<(String, MessageHeader, Vec<u8>), ReadError>> {
        let mut topics = topics(&this.summary);
        let mut at = MAGIC.len() as u64;
        let mut pending: VecDeque<Record<'static>> = VecDeque::new();
        let mut done = false;
        std::iter::from_fn(move || {
            loop {
                if done {
                    return None;
                }
                let Some(record) = pending.pop_front() else {
                    let framed = match frame_at(&this.source, at, this.data_end) {
                        Ok(Some(f)) => f,
                        Ok(None) => return None,
                        Err(e) => {
                            done = true;
                            return Some(Err(this.corrupt(e.to_string())));
                        }
                    };
                    at = framed.end();
                    let read = || read_record(&this.source, &framed);
                    let records = match framed.op {
                        op::CHUNK => read().and_then(|r| match r {
                            Record::Chunk { header, data } => chunk_records(&header, &data),
                            _ => Err("not a chunk".into()),
                        }),
                        op::MESSAGE | op::CHANNEL => read().map(|r| vec![r]),
                        op::DATA_END | op::FOOTER => {
                            done = true;
                            return None;
                        }
                        _ => continue,
                    };
                    match records {
                        Ok(r) => pending.extend(r),
                        Err(e) => {
                            done = true;
                            return Some(Err(this.corrupt(e)));
                        }
                    }
                    continue;
                };
                match record {
                    Record::Channel(c) => {
                        topics.insert(c.id, c.topic);
                    }
                    Record::Message { header, data } => {
                        let Some(topic) = topics.get(&header.channel_id) else {
                            done = true;
                            return Some(Err(this.corrupt(format!(
                                "message {} is on channel {}, which the file does not define",
                                header.sequence, header.channel_id
                            ))));
                        };
                        return Some(Ok((topic.clone(), header, data.into_owned())));
                    }
                    _ => {}
                }
            }
        })
    }

    /// The recorded scene: the first message on `/scene`, which the recorder writes
    /// first, so reading stops in the first chunk.
    pub fn scene(&self) -> Result<v1::SceneDescription, ReadError> {
        for m in self.raw() {
            let (topic, header, data) = m?;
            if topic == TOPIC_SCENE {
                return self.decode(&topic, &header, &data);
            }
        }
        Err(ReadError::NotARecording {
            file: self.file.clone(),
            message: format!("it has no message on {TOPIC_SCENE}"),
        })
    }

    pub fn poses(&self) -> Result<Vec<Stamped<v1::DevicePose>>, ReadError> {
        self.topic(TOPIC_POSES)
    }

    pub fn surfaces(&self) -> Result<Vec<Stamped<v1::SurfaceFrame>>, ReadError> {
        self.topic(TOPIC_SURFACE)
    }

    pub fn instrument_states(&self) -> Result<Vec<Stamped<v1::InstrumentState>>, ReadError> {
        self.topic(TOPIC_INSTRUMENTS)
    }

    pub fn events(&self) -> Result<Vec<Stamped<v1::Event>>, ReadError> {
        self.topic(TOPIC_EVENTS)
    }

    /// The Foxglove scene updates, decoded only when asked for.
    pub fn scene_updates(&self) -> Result<Vec<Stamped<SceneUpdate>>, ReadError> {
        self.topic(TOPIC_FOXGLOVE_SCENE)
    }

    fn decode<T: prost::Message + Default>(
        &self,
        topic: &str,
        header: &MessageHeader,
        data: &[u8],
    ) -> Result<T, ReadError> {
        T::decode(data).map_err(|e| ReadError::Decode {
            file: self.file.clone(),
            topic: topic.to_string(),
            sequence: header.sequence,
            message: e.to_string(),
        })
    }

    fn corrupt(&self, message: String) -> ReadError {
        ReadError::Corrupt {
            file: self.file.clone(),
            message,
        }
    }
}
