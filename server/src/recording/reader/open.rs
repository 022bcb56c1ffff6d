//! Opening a recording: a finished file from its end (footer, summary, the
//! metadata its index points to), a file without a summary walked from the start
//! a record prefix at a time; and the recording's description from its metadata.

use super::*;

impl Recording {
    pub(super) fn from_source(
        file: String,
        source: Source,
        unfinished: bool,
    ) -> Result<Self, ReadError> {
        let io = |e: std::io::Error| ReadError::Io {
            file: file.clone(),
            source: Arc::new(e),
        };
        let len = source.len().map_err(io)?;
        let magic = MAGIC.len() as u64;
        let mut head = [0u8; 8];
        if len < magic || source.read_exact_at(0, &mut head).is_err() || head[..] != MAGIC[..] {
            return Err(ReadError::NotMcap { file });
        }
        let mut tail = [0u8; 8];
        let footed = len >= 2 * magic
            && source.read_exact_at(len - magic, &mut tail).is_ok()
            && tail[..] == MAGIC[..];
        match (footed, unfinished) {
            (true, _) => Self::finished(file, source, len),
            (false, true) => Self::walked(file, source, len),
            (false, false) => Err(ReadError::Truncated { file }),
        }
    }

    /// A file with its footer: the summary it points to, then the metadata.
    fn finished(file: String, source: Source, len: u64) -> Result<Self, ReadError> {
        let corrupt = |message: String| ReadError::Corrupt {
            file: file.clone(),
            message,
        };
        if len < MAGIC.len() as u64 + FOOTER_AND_MAGIC {
            return Err(corrupt("it is too short for a footer".into()));
        }
        let footer_at = len - FOOTER_AND_MAGIC;
        let footer = source
            .read_at(footer_at, FOOTER_AND_MAGIC, FOOTER_AND_MAGIC)
            .map_err(|e| corrupt(e.to_string()))?;
        if footer[0] != op::FOOTER {
            return Err(corrupt(format!("no footer record at byte {footer_at}")));
        }
        let summary_start = u64::from_le_bytes(footer[9..17].try_into().expect("8 bytes"));
        if summary_start == 0 {
            return Err(ReadError::Truncated { file });
        }
        if summary_start > footer_at || footer_at - summary_start > MAX_SUMMARY_BYTES {
            return Err(corrupt(format!(
                "its footer puts the summary at byte {summary_start}, which is not within \
                 {MAX_SUMMARY_BYTES} bytes before the footer at byte {footer_at}"
            )));
        }
        let summary = {
            let mut cursor = source.cursor();
            let mut reader = SummaryReader::new_with_options(
                SummaryReaderOptions::default()
                    .with_file_size(len)
                    .with_record_length_limit(MAX_SUMMARY_BYTES as usize),
            );
            while let Some(event) = reader.next_event() {
                match event.map_err(|e| corrupt(e.to_string()))? {
                    SummaryReadEvent::ReadRequest(n) => {
                        let read = cursor
                            .read(reader.insert(n))
                            .map_err(|e| corrupt(e.to_string()))?;
                        reader.notify_read(read);
                    }
                    SummaryReadEvent::SeekRequest(to) => {
                        let at = cursor.seek(to).map_err(|e| corrupt(e.to_string()))?;
                        reader.notify_seeked(at);
                    }
                }
            }
            reader
                .finish()
                .ok_or_else(|| ReadError::Truncated { file: file.clone() })?
        };
        let not_ours = |message: String| ReadError::NotARecording {
            file: file.clone(),
            message,
        };
        let index = summary
            .metadata_indexes
            .iter()
            .find(|m| m.name == METADATA_NAME)
            .ok_or_else(|| not_ours(format!("it has no `{METADATA_NAME}` metadata record")))?;
        let record = source
            .read_at(index.offset, index.length, MAX_RECORD_BYTES)
            .map_err(|e| corrupt(format!("its metadata index: {e}")))
            .and_then(|b| parse_one(&b, index.offset).map_err(corrupt))?;
        let Record::Metadata(metadata) = record else {
            return Err(corrupt(
                "its metadata index points at another record".into(),
            ));
        };
        let meta = meta_from(&file, metadata.metadata)?;
        let surface: Vec<u16> = summary
            .channels
            .values()
            .filter(|c| c.topic == TOPIC_SURFACE)
            .map(|c| c.id)
            .collect();
        let mut chunks: Vec<ChunkAt> = summary
            .chunk_indexes
            .iter()
            .map(|c| ChunkAt {
                at: c.chunk_start_offset,
                surface: (!c.message_index_offsets.is_empty()).then(|| {
                    c.message_index_offsets
                        .keys()
                        .any(|id| surface.contains(id))
                }),
            })
            .collect();
        chunks.sort_by_key(|c| c.at);
        Ok(Recording {
            file,
            source,
            meta,
            summary,
            chunks,
            data_end: summary_start,
            complete: true,
        })
    }

    /// A file without its footer, walked (see the type's documentation). The walk
    /// ends at the first record cut short or damaged: what `recover` would keep,
    /// but for damage inside a chunk not opened here, which the reading that
    /// reaches it reports.
    fn walked(file: String, source: Source, len: u64) -> Result<Self, ReadError> {
        let corrupt = |message: String| ReadError::Corrupt {
            file: file.clone(),
            message,
        };
        let mut schemas: HashMap<u16, Arc<Schema<'static>>> = HashMap::new();
        let mut channels: HashMap<u16, Arc<Channel<'static>>> = HashMap::new();
        let add = |schemas: &mut HashMap<u16, Arc<Schema<'static>>>,
                   channels: &mut HashMap<u16, Arc<Channel<'static>>>,
                   record: Record<'static>| match record {
            Record::Schema { header, data } => {
                schemas.entry(header.id).or_insert_with(|| {
                    Arc::new(Schema {
                        id: header.id,
                        name: header.name,
                        encoding: header.encoding,
                        data,
                    })
                });
            }
            Record::Channel(c) => {
                let schema = schemas.get(&c.schema_id).cloned();
                channels.entry(c.id).or_insert_with(|| {
                    Arc::new(Channel {
                        id: c.id,
                        topic: c.topic,
                        schema,
                        message_encoding: c.message_encoding,
                        metadata: c.metadata,
                    })
                });
            }
            _ => {}
        };
        let mut metadata = None;
        let mut chunks = Vec::new();
        let mut newest = VecDeque::with_capacity(MAX_DURATION_CHUNKS);
        let mut opened = 0;
        let mut at = MAGIC.len() as u64;
        let mut walked = 0u64;
        // Whether the walk reached the data section's end rather than a record cut
        // short or damaged.
        let mut ended = false;
        while let Ok(Some(framed)) = frame_at(&source, at, len) {
            walked += 1;
            if walked > MAX_WALKED_RECORDS {
                return Err(corrupt(format!(
                    "it has more than {MAX_WALKED_RECORDS} records and no summary; \
                     recovering it writes one"
                )));
            }
            match framed.op {
                op::CHUNK if metadata.is_none() && opened < MAX_HEAD_CHUNKS => {
                    opened += 1;
                    let records = match read_record(&source, &framed) {
                        Ok(Record::Chunk { header, data }) => chunk_records(&header, &data),
                        Ok(_) => Err("not a chunk".into()),
                        Err(e) => Err(e),
                    };
                    let Ok(records) = records else { break };
                    let mut surface = false;
                    for r in records {
                        if let Record::Message { header, .. } = &r {
                            surface |= channels
                                .get(&header.channel_id)
                                .is_some_and(|c| c.topic == TOPIC_SURFACE);
                        }
                        add(&mut schemas, &mut channels, r);
                    }
                    chunks.push(ChunkAt {
                        at: framed.at,
                        surface: Some(surface),
                    });
                }
                op::CHUNK => {
                    // Only the newest are ever opened (for the duration).
                    if newest.len() == MAX_DURATION_CHUNKS {
                        newest.pop_front();
                    }
                    newest.push_back(ChunkAt {
                        at: framed.at,
                        surface: None,
                    });
                }
                op::SCHEMA | op::CHANNEL | op::METADATA => match read_record(&source, &framed) {
                    Ok(Record::Metadata(m)) if m.name == METADATA_NAME => metadata = Some(m),
                    Ok(r) => add(&mut schemas, &mut channels, r),
                    Err(_) => break,
                },
                op::DATA_END | op::FOOTER => {
                    ended = true;
                    break;
                }
                _ => {}
            }
            at = framed.end();
        }
        let Some(metadata) = metadata else {
            if !ended {
                return Err(ReadError::CutBeforeDescription { file, end: at });
            }
            return Err(ReadError::NotARecording {
                file,
                message: format!(
                    "it has no `{METADATA_NAME}` metadata record in what it holds so far"
                ),
            });
        };
        let meta = meta_from(&file, metadata.metadata)?;
        chunks.extend(newest);
        Ok(Recording {
            file,
            source,
            meta,
            summary: Summary {
                schemas,
                channels,
                ..Summary::default()
            },
            chunks,
            data_end: at,
            complete: false,
        })
    }
}

/// The recording's description from its `laparo.scene` metadata fields.
fn meta_from(file: &str, mut fields: BTreeMap<String, String>) -> Result<RecordingMeta, ReadError> {
    let not_ours = |message: String| ReadError::NotARecording {
        file: file.to_string(),
        message,
    };
    let mut take = |key: &str| {
        fields
            .remove(key)
            .ok_or_else(|| not_ours(format!("its `{METADATA_NAME}` metadata has no `{key}`")))
    };
    let format_version = take("format_version")?;
    if format_version != FORMAT_VERSION {
        return Err(ReadError::UnsupportedVersion {
            file: file.to_string(),
            found: format_version,
        });
    }
    let start = take("start_unix_ns")?;
    Ok(RecordingMeta {
        format_version,
        session_id: take("session_id")?,
        scene: take("scene")?,
        start_unix_ns: start
            .parse()
            .map_err(|_| not_ours(format!("its start time `{start}` is not a number of ns")))?,
        scene_toml: take("scene_toml")?,
        scene_dir: fields.remove("scene_dir").map(std::path::PathBuf::from),
    })
}
