//! ROS 2 over DDS, spoken directly through RustDDS: topic and type naming, the QoS profiles
//! of `rclcpp`, and readers and writers of raw CDR messages.
//!
//! A ROS 2 topic `/scan` of type `sensor_msgs/msg/LaserScan` is the DDS topic `rt/scan` of
//! type `sensor_msgs::msg::dds_::LaserScan_` (the naming every rmw implementation uses, so
//! that nodes on different middlewares meet). Samples are XCDR1 (`CDR_LE`/`CDR_BE`) without
//! a key. The messages are encoded and decoded by `slam_io::ros_msg` (one implementation,
//! shared with the bag reader and the MCAP writer); the adapters here only move the 4-byte
//! encapsulation header between the bytes and the DDS payload's representation identifier.

use crate::error::RosError;
use bytes::Bytes;
use rustdds::no_key::{
    DataReader, DataWriter, Decode, DefaultDecoder, DeserializerAdapter, SerializerAdapter,
};
use rustdds::policy::{Durability, History, Reliability};
use rustdds::{
    DomainParticipant, Publisher, QosPolicies, QosPolicyBuilder, RepresentationIdentifier,
    Subscriber, TopicKind,
};

/// A message as CDR bytes, its 4-byte encapsulation header included (what
/// `slam_io::ros_msg`'s encoders give and its decoders take).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawCdr(pub Vec<u8>);

/// Why a raw CDR message could not go on or come off the wire.
#[derive(Debug, thiserror::Error)]
#[error("raw CDR: {0}")]
pub struct RawCdrError(String);

/// The adapter between [`RawCdr`] and a DDS payload: writes `CDR_LE`, reads `CDR_LE` and
/// `CDR_BE` (the decoders read either byte order from the header).
pub struct RawCdrAdapter;

impl SerializerAdapter<RawCdr> for RawCdrAdapter {
    type Error = RawCdrError;

    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }

    fn to_bytes(value: &RawCdr) -> Result<Bytes, RawCdrError> {
        match value.0.get(..4) {
            Some([0, 1, _, _]) => Ok(Bytes::copy_from_slice(&value.0[4..])),
            _ => Err(RawCdrError(
                "a message must start with the CDR_LE header 00 01".into(),
            )),
        }
    }
}

/// The decoder of [`RawCdrAdapter`]: puts the payload's representation identifier back in
/// front of its bytes.
#[derive(Clone, Copy)]
pub struct RawCdrDecoder;

impl Decode<'_, RawCdr> for RawCdrDecoder {
    type Error = RawCdrError;

    fn decode_bytes(
        self,
        input_bytes: &[u8],
        encoding: RepresentationIdentifier,
    ) -> Result<RawCdr, RawCdrError> {
        let head: [u8; 4] = if encoding == RepresentationIdentifier::CDR_LE {
            [0, 1, 0, 0]
        } else if encoding == RepresentationIdentifier::CDR_BE {
            [0, 0, 0, 0]
        } else {
            return Err(RawCdrError(format!(
                "representation {encoding:?}: only CDR_LE and CDR_BE (XCDR1) are read"
            )));
        };
        let mut v = Vec::with_capacity(4 + input_bytes.len());
        v.extend_from_slice(&head);
        v.extend_from_slice(input_bytes);
        Ok(RawCdr(v))
    }
}

impl DeserializerAdapter<RawCdr> for RawCdrAdapter {
    type Error = RawCdrError;
    type Decoded = RawCdr;

    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        &[
            RepresentationIdentifier::CDR_LE,
            RepresentationIdentifier::CDR_BE,
        ]
    }

    fn transform_decoded(decoded: RawCdr) -> RawCdr {
        decoded
    }
}

impl DefaultDecoder<RawCdr> for RawCdrAdapter {
    type Decoder = RawCdrDecoder;
    const DECODER: RawCdrDecoder = RawCdrDecoder;
}

/// A reader of one topic's raw messages.
pub type Reader = DataReader<RawCdr, RawCdrAdapter>;
/// A writer of one topic's raw messages.
pub type Writer = DataWriter<RawCdr, RawCdrAdapter>;

/// The QoS profiles of `rclcpp` (`rmw_qos_profile_*`) the node uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Profile {
    /// `sensor_data`: best effort, keep last 5, volatile (a reader of it matches reliable and
    /// best-effort writers).
    SensorData,
    /// The default: reliable, keep last 10, volatile.
    Default,
    /// Latched (`/map`, `/tf_static`): reliable, keep last 1, transient local (a late reader
    /// receives the last message).
    Latched,
    /// `/tf`: reliable, keep last 100, volatile (tf2_ros's broadcaster and listener).
    Tf,
}

impl Profile {
    /// The DDS policies.
    pub fn qos(self) -> QosPolicies {
        let reliable = Reliability::Reliable {
            max_blocking_time: rustdds::Duration::from_millis(100),
        };
        let (reliability, depth, durability) = match self {
            Profile::SensorData => (Reliability::BestEffort, 5, Durability::Volatile),
            Profile::Default => (reliable, 10, Durability::Volatile),
            Profile::Latched => (reliable, 1, Durability::TransientLocal),
            Profile::Tf => (reliable, 100, Durability::Volatile),
        };
        QosPolicyBuilder::new()
            .reliability(reliability)
            .history(History::KeepLast { depth })
            .durability(durability)
            .build()
    }

    /// The name used in the docs' QoS table.
    pub fn describe(self) -> &'static str {
        match self {
            Profile::SensorData => "best effort, keep last 5, volatile (sensor data)",
            Profile::Default => "reliable, keep last 10, volatile",
            Profile::Latched => "reliable, keep last 1, transient local",
            Profile::Tf => "reliable, keep last 100, volatile",
        }
    }
}

/// The DDS topic name of a ROS 2 topic: `rt` followed by the fully qualified name
/// (`/scan` → `rt/scan`; a relative name is taken from the root namespace).
pub fn dds_topic_name(ros_topic: &str) -> String {
    if ros_topic.starts_with('/') {
        format!("rt{ros_topic}")
    } else {
        format!("rt/{ros_topic}")
    }
}

/// A DDS participant with one publisher and one subscriber: the node's handle on the bus.
pub struct Participant {
    dp: DomainParticipant,
    publisher: Publisher,
    subscriber: Subscriber,
}

impl Participant {
    /// Joins DDS domain `domain_id` (ROS 2's `ROS_DOMAIN_ID`, 0–232), on every interface.
    ///
    /// There is no loopback-only mode (`ROS_LOCALHOST_ONLY`): RustDDS 0.13.1 can announce
    /// only 127.0.0.1 (`DomainParticipantBuilder::with_only_networks`), but it ignores the
    /// loopback locators its peers announce (`RtpsReaderProxy::not_loopback`, the route
    /// selection in `rtps/transmit.rs`), so it cannot talk to a peer held to loopback.
    pub fn new(domain_id: u16) -> Result<Self, RosError> {
        if domain_id > 232 {
            return Err(RosError::Dds(format!(
                "domain id {domain_id}: ROS 2 domain ids are 0–232"
            )));
        }
        let dds = |e: &dyn std::fmt::Display| RosError::Dds(e.to_string());
        let dp = DomainParticipant::new(domain_id).map_err(|e| dds(&e))?;
        let qos = QosPolicyBuilder::new().build();
        let publisher = dp.create_publisher(&qos).map_err(|e| dds(&e))?;
        let subscriber = dp.create_subscriber(&qos).map_err(|e| dds(&e))?;
        Ok(Participant {
            dp,
            publisher,
            subscriber,
        })
    }

    /// The DDS topic `dds_topic` (shown as `shown` in errors) of `ros_type`.
    fn topic(
        &self,
        dds_topic: String,
        shown: &str,
        ros_type: &str,
        profile: Profile,
    ) -> Result<rustdds::Topic, RosError> {
        self.dp
            .create_topic(
                dds_topic,
                slam_io::ros_msg::dds_type_name(ros_type),
                &profile.qos(),
                TopicKind::NoKey,
            )
            .map_err(|e| RosError::Dds(format!("topic {shown}: {e}")))
    }

    /// A writer of DDS topic `dds_topic` (shown as `shown` in errors).
    fn dds_writer(
        &self,
        dds_topic: String,
        shown: &str,
        ros_type: &str,
        profile: Profile,
    ) -> Result<Writer, RosError> {
        let topic = self.topic(dds_topic, shown, ros_type, profile)?;
        self.publisher
            .create_datawriter_no_key::<RawCdr, RawCdrAdapter>(&topic, Some(profile.qos()))
            .map_err(|e| RosError::Dds(format!("writer of {shown}: {e}")))
    }

    /// The participant's GUID (RTPS: 12-byte prefix, 4-byte entity id), ROS 2's gid of it.
    pub fn gid(&self) -> [u8; 16] {
        rustdds::RTPSEntity::guid(&self.dp).to_bytes()
    }

    /// The writer of the ROS 2 graph's `ros_discovery_info` topic (no `rt` prefix, type
    /// `rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_`, reliable, keep last 1,
    /// transient local, as `rmw_dds_common`'s graph cache publishes it).
    pub fn discovery_info_writer(&self) -> Result<Writer, RosError> {
        use crate::graph::{DISCOVERY_TOPIC, DISCOVERY_TYPE};
        let topic = DISCOVERY_TOPIC.to_string();
        self.dds_writer(topic, DISCOVERY_TOPIC, DISCOVERY_TYPE, Profile::Latched)
    }

    /// A writer of `ros_topic` (type `pkg/msg/Type`) with `profile`.
    pub fn writer(
        &self,
        ros_topic: &str,
        ros_type: &str,
        profile: Profile,
    ) -> Result<Writer, RosError> {
        self.dds_writer(dds_topic_name(ros_topic), ros_topic, ros_type, profile)
    }

    /// A reader of `ros_topic` (type `pkg/msg/Type`) with `profile`.
    pub fn reader(
        &self,
        ros_topic: &str,
        ros_type: &str,
        profile: Profile,
    ) -> Result<Reader, RosError> {
        let topic = self.topic(dds_topic_name(ros_topic), ros_topic, ros_type, profile)?;
        self.subscriber
            .create_datareader_no_key::<RawCdr, RawCdrAdapter>(&topic, Some(profile.qos()))
            .map_err(|e| RosError::Dds(format!("reader of {ros_topic}: {e}")))
    }
}

/// Takes the next message of `reader` (of ROS topic `topic`, named in the error),
/// `Ok(None)` when none is waiting.
pub fn take(reader: &mut Reader, topic: &str) -> Result<Option<RawCdr>, RosError> {
    match reader.take_next_sample() {
        Ok(Some(s)) => Ok(Some(s.into_value())),
        Ok(None) => Ok(None),
        Err(e) => Err(RosError::Dds(format!("read of {topic}: {e}"))),
    }
}

/// The gid (RTPS GUID) of a reader or writer.
pub fn gid_of(entity: &dyn rustdds::RTPSEntity) -> [u8; 16] {
    entity.guid().to_bytes()
}

/// Writes `message` on `writer` (of ROS topic `topic`, named in the error). `Ok(false)`: not
/// written, because a reliable reader has not acknowledged the writer's history (its
/// depth) within the QoS's blocking time (100 ms): the message is dropped, not queued, so
/// a slow subscriber never holds the node up for longer.
pub fn write(writer: &Writer, topic: &str, message: Vec<u8>) -> Result<bool, RosError> {
    match writer.write(RawCdr(message), None) {
        Ok(()) => Ok(true),
        Err(rustdds::dds::result::WriteError::WouldBlock { .. }) => Ok(false),
        Err(e) => Err(RosError::Dds(format!("write on {topic}: {e}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topic_names_follow_ros2_naming() {
        assert_eq!(dds_topic_name("/scan"), "rt/scan");
        assert_eq!(dds_topic_name("scan"), "rt/scan");
        assert_eq!(dds_topic_name("/robot1/map"), "rt/robot1/map");
    }

    #[test]
    fn the_adapters_move_the_header_to_the_representation() {
        let msg = RawCdr(vec![0, 1, 0, 0, 7, 0, 0, 0]);
        let body = <RawCdrAdapter as SerializerAdapter<RawCdr>>::to_bytes(&msg).unwrap();
        assert_eq!(&body[..], &[7, 0, 0, 0]);
        let back = RawCdrDecoder
            .decode_bytes(&body, RepresentationIdentifier::CDR_LE)
            .unwrap();
        assert_eq!(back, msg);
        let be = RawCdrDecoder
            .decode_bytes(&[0, 0, 0, 7], RepresentationIdentifier::CDR_BE)
            .unwrap();
        assert_eq!(be.0, vec![0, 0, 0, 0, 0, 0, 0, 7]);
        assert!(RawCdrDecoder
            .decode_bytes(&body, RepresentationIdentifier::PL_CDR_LE)
            .is_err());
        assert!(
            <RawCdrAdapter as SerializerAdapter<RawCdr>>::to_bytes(&RawCdr(vec![0, 0])).is_err()
        );
    }
}
