//! The ROS 2 node graph: what makes the node visible to `ros2 node list` and `ros2 topic
//! info`. Each ROS 2 participant publishes, on the DDS topic `ros_discovery_info`, an
//! `rmw_dds_common/msg/ParticipantEntitiesInfo`: its gid and, per node it hosts, the node's
//! name and namespace and the gids of the node's readers and writers (the DDS discovery
//! itself knows participants and endpoints, not nodes). This is that message.
//!
//! ```text
//! rmw_dds_common/msg/Gid:                     uint8[16] data
//! rmw_dds_common/msg/NodeEntitiesInfo:        string<256> node_namespace, string<256> node_name,
//!                                             Gid[] reader_gid_seq, Gid[] writer_gid_seq
//! rmw_dds_common/msg/ParticipantEntitiesInfo: Gid gid, NodeEntitiesInfo[] node_entities_info_seq
//! ```
//!
//! The gids are 16 bytes (RTPS GUIDs), as in ROS 2 Iron and newer; Humble's `Gid` had 24
//! (the GUID and 8 zero bytes), so a Humble graph sees the node's topics but not the node.

/// The DDS topic of the graph messages (no `rt` prefix: not a ROS topic).
pub const DISCOVERY_TOPIC: &str = "ros_discovery_info";
/// Its ROS type.
pub const DISCOVERY_TYPE: &str = "rmw_dds_common/msg/ParticipantEntitiesInfo";

/// One node of a participant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeEntities {
    /// The namespace (`/` for the root).
    pub namespace: String,
    /// The name.
    pub name: String,
    /// The gids of the node's readers (subscriptions).
    pub readers: Vec<[u8; 16]>,
    /// The gids of the node's writers (publishers).
    pub writers: Vec<[u8; 16]>,
}

/// The CDR bytes (XCDR1, little endian, encapsulation header included) of a
/// `ParticipantEntitiesInfo` of participant `gid` hosting `nodes` (none: the participant
/// says its nodes are gone, as rmw does at shutdown).
pub fn encode_participant_entities_info(gid: &[u8; 16], nodes: &[NodeEntities]) -> Vec<u8> {
    // Alignment counts from the byte after the 4-byte encapsulation header.
    fn align4(b: &mut Vec<u8>) {
        while (b.len() - 4) % 4 != 0 {
            b.push(0);
        }
    }
    fn u32(b: &mut Vec<u8>, v: usize) {
        align4(b);
        b.extend_from_slice(&(v as u32).to_le_bytes());
    }
    fn string(b: &mut Vec<u8>, s: &str) {
        u32(b, s.len() + 1);
        b.extend_from_slice(s.as_bytes());
        b.push(0);
    }
    fn gids(b: &mut Vec<u8>, g: &[[u8; 16]]) {
        u32(b, g.len());
        g.iter().for_each(|g| b.extend_from_slice(g));
    }
    let mut b = vec![0, 1, 0, 0];
    b.extend_from_slice(gid);
    u32(&mut b, nodes.len());
    for n in nodes {
        string(&mut b, &n.namespace);
        string(&mut b, &n.name);
        gids(&mut b, &n.readers);
        gids(&mut b, &n.writers);
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn participant_entities_info_bytes_follow_xcdr1() {
        let gid = [7u8; 16];
        let node = NodeEntities {
            namespace: "/".into(),
            name: "slam".into(),
            readers: vec![[1; 16]],
            writers: vec![[2; 16], [3; 16]],
        };
        let b = encode_participant_entities_info(&gid, &[node]);
        // Worked by hand from the IDL: header, gid, 1 node, "/" (len 2 + 2 pad), "slam"
        // (len 5 + 3 pad), 1 reader gid, 2 writer gids.
        let mut want = vec![0, 1, 0, 0];
        want.extend([7; 16]);
        want.extend([1, 0, 0, 0]);
        want.extend([2, 0, 0, 0, b'/', 0, 0, 0]);
        want.extend([5, 0, 0, 0, b's', b'l', b'a', b'm', 0, 0, 0, 0]);
        want.extend([1, 0, 0, 0]);
        want.extend([1; 16]);
        want.extend([2, 0, 0, 0]);
        want.extend([2; 16]);
        want.extend([3; 16]);
        assert_eq!(b, want);
        let empty = encode_participant_entities_info(&gid, &[]);
        assert_eq!(empty.len(), 4 + 16 + 4);
    }
}
