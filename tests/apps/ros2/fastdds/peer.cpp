// A ROS 2 peer on eProsima Fast DDS (ROS 2's default middleware), independent of cufund: its types and their CDR
// come from fastddsgen on ros2_msgs.idl, its participant from an XML profile (loopback only). The tests run it
// against cufund's Cyclone DDS side.
//
//   peer PROFILE.xml DOMAIN info
//       prints the participant's configuration (transports, locators, peers) as one JSON line and exits.
//   peer PROFILE.xml DOMAIN sub SECONDS COUNT [--dump DIR] [--idle S] TOPIC=KIND[,reliable]...
//       subscribes to each DDS TOPIC (rt/imu) as KIND (imu, points, tf, pose: ROS 2's Imu, PointCloud2,
//       TFMessage, PoseStamped; best effort, which matches any writer, or reliable), prints one JSON line per sample
//       (type name, decoded fields) and, with --dump, writes the sample's serialized payload as received (encapsulation
//       included) to DIR/<n>.cdr; ends when every topic has COUNT samples, after SECONDS, or (--idle) S seconds after
//       the last sample.
//   peer PROFILE.xml DOMAIN pub SECONDS COUNT TOPIC=KIND [X Y Z] [--go-on-stdin]
//       publishes COUNT samples at 20 Hz once a reader matched (pose: a goal at X Y Z in frame "map"; imu:
//       sample k stamped k s with angular_velocity (0.1 k, 0.2, 0.3), linear_acceleration (1, 2, 9.81)), waits
//       for their acknowledgement, prints a JSON line per sample; gives up after SECONDS. With --go-on-stdin it
//       prints {"event":"waiting"} once matched and publishes after a line on its standard input (the caller
//       knows when the reader's side has matched the writer: discovery is not symmetric).
// Every line is flushed; exit status 0 when the expected samples went through, 1 otherwise, 2 for bad usage.

#include "ros2_msgs.h"
#include "ros2_msgsPubSubTypes.h"

#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

using namespace eprosima::fastdds::dds;
using eprosima::fastrtps::rtps::InstanceHandle_t;
using eprosima::fastrtps::rtps::Locator_t;
using eprosima::fastrtps::rtps::LocatorList_t;
using eprosima::fastrtps::rtps::SerializedPayload_t;

namespace {

std::mutex out_mutex;
std::atomic<int64_t> last_sample_ns{0};  // steady clock of the last sample received

int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

void emit(const std::string& line) {
  std::lock_guard<std::mutex> lock(out_mutex);
  std::fwrite(line.data(), 1, line.size(), stdout);
  std::fputc('\n', stdout);
  std::fflush(stdout);
}

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

std::string str(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\u%04x", c);
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string locators(const LocatorList_t& list) {
  std::string out = "[";
  bool first = true;
  for (const Locator_t& l : list) {
    std::ostringstream s;
    s << l;
    out += (first ? "" : ",") + str(s.str());
    first = false;
  }
  return out + "]";
}

// A type that keeps each sample's serialized payload as it arrived (the bytes on the wire after reassembly),
// under the DDS type name of the ROS 2 type it stands for; the peer decodes the bytes with fastddsgen's type.
struct RawSample {
  std::vector<unsigned char> bytes;
};

class RawType : public TopicDataType {
 public:
  explicit RawType(const std::string& name) {
    setName(name.c_str());
    m_typeSize = 16 * 1024 * 1024;
    m_isGetKeyDefined = false;
  }
  bool serialize(void* data, SerializedPayload_t* payload) override {
    auto* s = static_cast<RawSample*>(data);
    if (s->bytes.size() > payload->max_size) return false;
    std::memcpy(payload->data, s->bytes.data(), s->bytes.size());
    payload->length = static_cast<uint32_t>(s->bytes.size());
    return true;
  }
  bool deserialize(SerializedPayload_t* payload, void* data) override {
    auto* s = static_cast<RawSample*>(data);
    s->bytes.assign(payload->data, payload->data + payload->length);
    return true;
  }
  std::function<uint32_t()> getSerializedSizeProvider(void* data) override {
    return [data]() { return static_cast<uint32_t>(static_cast<RawSample*>(data)->bytes.size()); };
  }
  void* createData() override { return new RawSample(); }
  void deleteData(void* data) override { delete static_cast<RawSample*>(data); }
  bool getKey(void*, InstanceHandle_t*, bool) override { return false; }
};

template <class PubSub, class Msg>
bool decode(const RawSample& raw, Msg& msg) {
  PubSub type;
  SerializedPayload_t payload(static_cast<uint32_t>(raw.bytes.size()));
  std::memcpy(payload.data, raw.bytes.data(), raw.bytes.size());
  payload.length = static_cast<uint32_t>(raw.bytes.size());
  return type.deserialize(&payload, &msg);
}

std::string header(const std_msgs::msg::dds_::Header_& h) {
  return "\"sec\":" + std::to_string(h.stamp().sec()) + ",\"nanosec\":" + std::to_string(h.stamp().nanosec()) +
         ",\"frame_id\":" + str(h.frame_id());
}

std::string vec3(double x, double y, double z) { return "[" + num(x) + "," + num(y) + "," + num(z) + "]"; }

std::string quat(const geometry_msgs::msg::dds_::Quaternion_& q) {
  return "[" + num(q.x()) + "," + num(q.y()) + "," + num(q.z()) + "," + num(q.w()) + "]";
}

// The fields of one sample of KIND as JSON members ("" when it does not decode).
std::string fields(const std::string& kind, const RawSample& raw) {
  if (kind == "imu") {
    sensor_msgs::msg::dds_::Imu_ m;
    if (!decode<sensor_msgs::msg::dds_::Imu_PubSubType>(raw, m)) return "";
    const auto& w = m.angular_velocity();
    const auto& f = m.linear_acceleration();
    return header(m.header()) + ",\"orientation\":" + quat(m.orientation()) +
           ",\"orientation_covariance0\":" + num(m.orientation_covariance()[0]) +
           ",\"angular_velocity\":" + vec3(w.x(), w.y(), w.z()) +
           ",\"linear_acceleration\":" + vec3(f.x(), f.y(), f.z());
  }
  if (kind == "points") {
    sensor_msgs::msg::dds_::PointCloud2_ m;
    if (!decode<sensor_msgs::msg::dds_::PointCloud2_PubSubType>(raw, m)) return "";
    std::string fs = "[";
    for (size_t i = 0; i < m.fields().size(); ++i) {
      const auto& f = m.fields()[i];
      fs += (i ? "," : "") + std::string("[") + str(f.name()) + "," + std::to_string(f.offset()) + "," +
            std::to_string(f.datatype()) + "," + std::to_string(f.count()) + "]";
    }
    fs += "]";
    std::string first = "null";
    if (m.data().size() >= 12 && m.point_step() >= 12) {  // the first point's x, y, z (float32, LE)
      float xyz[3];
      std::memcpy(xyz, m.data().data(), 12);
      first = vec3(xyz[0], xyz[1], xyz[2]);
    }
    return header(m.header()) + ",\"height\":" + std::to_string(m.height()) +
           ",\"width\":" + std::to_string(m.width()) + ",\"fields\":" + fs +
           ",\"is_bigendian\":" + (m.is_bigendian() ? "true" : "false") +
           ",\"point_step\":" + std::to_string(m.point_step()) + ",\"row_step\":" + std::to_string(m.row_step()) +
           ",\"data_bytes\":" + std::to_string(m.data().size()) + ",\"first_point\":" + first +
           ",\"is_dense\":" + (m.is_dense() ? "true" : "false");
  }
  if (kind == "tf") {
    tf2_msgs::msg::dds_::TFMessage_ m;
    if (!decode<tf2_msgs::msg::dds_::TFMessage_PubSubType>(raw, m)) return "";
    std::string ts = "[";
    for (size_t i = 0; i < m.transforms().size(); ++i) {
      const auto& t = m.transforms()[i];
      const auto& p = t.transform().translation();
      ts += (i ? "," : "") + std::string("{") + header(t.header()) + ",\"child_frame_id\":" + str(t.child_frame_id()) +
            ",\"translation\":" + vec3(p.x(), p.y(), p.z()) + ",\"rotation\":" + quat(t.transform().rotation()) + "}";
    }
    return "\"transforms\":" + ts + "]";
  }
  if (kind == "pose") {
    geometry_msgs::msg::dds_::PoseStamped_ m;
    if (!decode<geometry_msgs::msg::dds_::PoseStamped_PubSubType>(raw, m)) return "";
    const auto& p = m.pose().position();
    return header(m.header()) + ",\"position\":" + vec3(p.x(), p.y(), p.z()) +
           ",\"orientation\":" + quat(m.pose().orientation());
  }
  return "";
}

const std::map<std::string, std::string> TYPE_NAMES = {
    {"imu", "sensor_msgs::msg::dds_::Imu_"},
    {"points", "sensor_msgs::msg::dds_::PointCloud2_"},
    {"tf", "tf2_msgs::msg::dds_::TFMessage_"},
    {"pose", "geometry_msgs::msg::dds_::PoseStamped_"},
};

struct Endpoint {
  std::string topic, kind;
  bool reliable = false;  // a reader: reliable (matches only reliable writers) or best effort (matches both)
};

bool parse_endpoint(const std::string& arg, Endpoint& e) {
  auto eq = arg.find('=');
  if (eq == std::string::npos) return false;
  e.topic = arg.substr(0, eq);
  e.kind = arg.substr(eq + 1);
  const std::string suffix = ",reliable";
  if (e.kind.size() > suffix.size() && e.kind.compare(e.kind.size() - suffix.size(), suffix.size(), suffix) == 0) {
    e.reliable = true;
    e.kind.resize(e.kind.size() - suffix.size());
  }
  return TYPE_NAMES.count(e.kind) == 1;
}

class ReaderListener : public DataReaderListener {
 public:
  ReaderListener(Endpoint e, std::string dump, std::atomic<int>& counter)
      : endpoint_(std::move(e)), dump_(std::move(dump)), counter_(counter) {}
  void on_data_available(DataReader* reader) override {
    RawSample raw;
    SampleInfo info;
    while (reader->take_next_sample(&raw, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      int n = counter_++;
      std::string line = "{\"event\":\"sample\",\"topic\":" + str(endpoint_.topic) +
                         ",\"type\":" + str(reader->type().get_type_name()) +
                         ",\"bytes\":" + std::to_string(raw.bytes.size()) + ",\"n\":" + std::to_string(n);
      if (!dump_.empty()) {
        std::string path = dump_ + "/" + std::to_string(n) + ".cdr";
        std::ofstream(path, std::ios::binary)
            .write(reinterpret_cast<const char*>(raw.bytes.data()), static_cast<std::streamsize>(raw.bytes.size()));
        line += ",\"file\":" + str(path);
      }
      std::string f = fields(endpoint_.kind, raw);
      line += f.empty() ? ",\"decoded\":false}" : ",\"decoded\":true," + f + "}";
      emit(line);
      ++received;
      last_sample_ns = steady_ns();
    }
  }
  void on_subscription_matched(DataReader*, const SubscriptionMatchedStatus& status) override {
    emit("{\"event\":\"matched\",\"topic\":" + str(endpoint_.topic) +
         ",\"count\":" + std::to_string(status.current_count) + "}");
  }
  std::atomic<int> received{0};

 private:
  Endpoint endpoint_;
  std::string dump_;
  std::atomic<int>& counter_;
};

class WriterListener : public DataWriterListener {
 public:
  void on_publication_matched(DataWriter*, const PublicationMatchedStatus& status) override {
    matched = status.current_count;
    emit("{\"event\":\"matched\",\"count\":" + std::to_string(status.current_count) + "}");
  }
  std::atomic<int> matched{0};
};

int usage() {
  std::fprintf(stderr,
               "usage: peer PROFILE.xml DOMAIN info\n"
               "       peer PROFILE.xml DOMAIN sub SECONDS COUNT [--dump DIR] [--idle S] TOPIC=KIND[,reliable]...\n"
               "       peer PROFILE.xml DOMAIN pub SECONDS COUNT TOPIC=KIND [X Y Z] [--go-on-stdin]\n"
               "KIND: imu, points, tf, pose\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) return usage();
  const std::string profile_file = argv[1], command = argv[3];
  const int domain = std::atoi(argv[2]);
  auto* factory = DomainParticipantFactory::get_instance();
  if (factory->load_XML_profiles_file(profile_file) != ReturnCode_t::RETCODE_OK) {
    std::fprintf(stderr, "peer: cannot load the XML profile %s\n", profile_file.c_str());
    return 2;
  }
  DomainParticipant* participant = factory->create_participant_with_profile(domain, "cufund_loopback");
  if (participant == nullptr) {
    std::fprintf(stderr, "peer: no participant from profile cufund_loopback of %s\n", profile_file.c_str());
    return 2;
  }
  const DomainParticipantQos& qos = participant->get_qos();
  const auto& builtin = qos.wire_protocol().builtin;
  std::string transports = "[";
  for (size_t i = 0; i < qos.transport().user_transports.size(); ++i) {
    auto udp = std::dynamic_pointer_cast<eprosima::fastdds::rtps::UDPv4TransportDescriptor>(
        qos.transport().user_transports[i]);
    std::string wl = "[";
    if (udp) {
      for (size_t k = 0; k < udp->interfaceWhiteList.size(); ++k)
        wl += (k ? "," : "") + str(udp->interfaceWhiteList[k]);
    }
    transports += (i ? "," : "") + std::string("{\"kind\":") + str(udp ? "UDPv4" : "other") +
                  ",\"interface_whitelist\":" + wl + "]}";
  }
  transports += "]";
  emit("{\"event\":\"participant\",\"domain\":" + std::to_string(domain) + ",\"use_builtin_transports\":" +
       (qos.transport().use_builtin_transports ? "true" : "false") + ",\"user_transports\":" + transports +
       ",\"metatraffic_unicast\":" + locators(builtin.metatrafficUnicastLocatorList) + ",\"metatraffic_multicast\":" +
       locators(builtin.metatrafficMulticastLocatorList) + ",\"initial_peers\":" + locators(builtin.initialPeersList) +
       ",\"default_unicast\":" + locators(qos.wire_protocol().default_unicast_locator_list) +
       ",\"default_multicast\":" + locators(qos.wire_protocol().default_multicast_locator_list) + "}");
  int status = 0;
  if (command == "info") {
  } else if (command == "sub" && argc >= 7) {
    const double seconds = std::atof(argv[4]);
    const int count = std::atoi(argv[5]);
    std::string dump;
    double idle = 0;
    std::vector<Endpoint> endpoints;
    for (int i = 6; i < argc; ++i) {
      if (std::string(argv[i]) == "--dump" && i + 1 < argc) {
        dump = argv[++i];
        continue;
      }
      if (std::string(argv[i]) == "--idle" && i + 1 < argc) {
        idle = std::atof(argv[++i]);
        continue;
      }
      Endpoint e;
      if (!parse_endpoint(argv[i], e)) return usage();
      endpoints.push_back(e);
    }
    Subscriber* sub = participant->create_subscriber(SUBSCRIBER_QOS_DEFAULT);
    std::atomic<int> counter{0};
    std::vector<std::unique_ptr<ReaderListener>> listeners;
    std::vector<DataReader*> readers;
    for (const Endpoint& e : endpoints) {
      TypeSupport type(new RawType(TYPE_NAMES.at(e.kind)));
      type.register_type(participant);
      Topic* topic = participant->create_topic(e.topic, type.get_type_name(), TOPIC_QOS_DEFAULT);
      DataReaderQos rq = DATAREADER_QOS_DEFAULT;
      rq.reliability().kind = e.reliable ? RELIABLE_RELIABILITY_QOS : BEST_EFFORT_RELIABILITY_QOS;
      rq.durability().kind = VOLATILE_DURABILITY_QOS;
      rq.history().kind = KEEP_LAST_HISTORY_QOS;
      rq.history().depth = 100;
      rq.endpoint().history_memory_policy = eprosima::fastrtps::rtps::DYNAMIC_RESERVE_MEMORY_MODE;
      listeners.emplace_back(new ReaderListener(e, dump, counter));
      readers.push_back(sub->create_datareader(topic, rq, listeners.back().get()));
      if (readers.back() == nullptr) {
        std::fprintf(stderr, "peer: no reader for %s\n", e.topic.c_str());
        return 2;
      }
    }
    emit("{\"event\":\"ready\"}");
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    bool done = false;
    while (!done && std::chrono::steady_clock::now() < end) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      done = true;
      bool each = true;
      for (auto& l : listeners) {
        done = done && l->received >= count;
        each = each && l->received > 0;
      }
      if (idle > 0 && each && steady_ns() - last_sample_ns > static_cast<int64_t>(idle * 1e9)) done = true;
    }
    for (DataReader* r : readers) r->set_listener(nullptr);
    status = done ? 0 : 1;
  } else if (command == "pub" && argc >= 7) {
    const double seconds = std::atof(argv[4]);
    const int count = std::atoi(argv[5]);
    Endpoint e;
    if (!parse_endpoint(argv[6], e) || (e.kind != "pose" && e.kind != "imu")) return usage();
    double xyz[3] = {0, 0, 0};
    bool go_on_stdin = false;
    for (int i = 7, k = 0; i < argc; ++i) {
      if (std::string(argv[i]) == "--go-on-stdin")
        go_on_stdin = true;
      else if (k < 3)
        xyz[k++] = std::atof(argv[i]);
    }
    TypeSupport type(e.kind == "pose"
                         ? static_cast<TopicDataType*>(new geometry_msgs::msg::dds_::PoseStamped_PubSubType())
                         : static_cast<TopicDataType*>(new sensor_msgs::msg::dds_::Imu_PubSubType()));
    type.register_type(participant);
    Topic* topic = participant->create_topic(e.topic, type.get_type_name(), TOPIC_QOS_DEFAULT);
    Publisher* pub = participant->create_publisher(PUBLISHER_QOS_DEFAULT);
    DataWriterQos wq = DATAWRITER_QOS_DEFAULT;
    wq.reliability().kind = RELIABLE_RELIABILITY_QOS;
    wq.durability().kind = VOLATILE_DURABILITY_QOS;
    wq.history().kind = KEEP_LAST_HISTORY_QOS;
    wq.history().depth = 10;
    WriterListener listener;
    DataWriter* writer = pub->create_datawriter(topic, wq, &listener);
    emit("{\"event\":\"ready\",\"type\":" + str(type.get_type_name()) + "}");
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (listener.matched == 0 && std::chrono::steady_clock::now() < end)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    int sent = 0;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the reader's side of discovery settles
    if (go_on_stdin && listener.matched > 0) {  // the caller knows when the reader has matched this writer too
      emit("{\"event\":\"waiting\"}");
      std::string go;
      std::getline(std::cin, go);
    }
    for (int k = 0; k < count && listener.matched > 0 && std::chrono::steady_clock::now() < end; ++k) {
      bool ok;
      if (e.kind == "pose") {
        geometry_msgs::msg::dds_::PoseStamped_ m;
        m.header().stamp().sec(k);
        m.header().frame_id("map");
        m.pose().position().x(xyz[0]);
        m.pose().position().y(xyz[1]);
        m.pose().position().z(xyz[2]);
        m.pose().orientation().w(1.0);
        ok = writer->write(&m);
      } else {
        sensor_msgs::msg::dds_::Imu_ m;
        m.header().stamp().sec(k);
        m.header().frame_id("imu_link");
        m.orientation().w(1.0);
        m.orientation_covariance()[0] = -1.0;
        m.angular_velocity().x(0.1 * k);
        m.angular_velocity().y(0.2);
        m.angular_velocity().z(0.3);
        m.linear_acceleration().x(1.0);
        m.linear_acceleration().y(2.0);
        m.linear_acceleration().z(9.81);
        ok = writer->write(&m);
      }
      if (ok) {
        ++sent;
        emit("{\"event\":\"sent\",\"k\":" + std::to_string(k) + "}");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    writer->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(2, 0));
    status = sent == count ? 0 : 1;
  } else {
    return usage();
  }
  participant->delete_contained_entities();
  factory->delete_participant(participant);
  return status;
}
