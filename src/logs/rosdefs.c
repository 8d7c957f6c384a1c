/* Message definitions of the types the encoders write, in the text form ROS
 * bags (message_definition) and MCAP "ros1msg"/"ros2msg" schemas carry:
 * the type's fields, then each nested type after a line of '=' and
 * "MSG: <type>". Field lists follow the ROS interface definitions. */
#include "logs_impl.h"

#define SEP "================================================================================\n"
#define HEADER1 "MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n"
#define HEADER2 "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" SEP \
                "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"

#define IMAGE(H)                                                                                             \
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\n" \
    "uint8[] data\n" SEP H
#define CIMAGE(H) "std_msgs/Header header\nstring format\nuint8[] data\n" SEP H
/* ROS 2 spells the CameraInfo matrices d, k, r, p */
#define CAMINFO(H, D, K, R, P)                                                                               \
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] " D "\n"        \
    "float64[9] " K "\nfloat64[9] " R "\nfloat64[12] " P "\nuint32 binning_x\nuint32 binning_y\n"              \
    "sensor_msgs/RegionOfInterest roi\n" SEP H SEP                                                          \
    "MSG: sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\n"      \
    "bool do_rectify\n"
#define TFMSG(H)                                                                                             \
    "geometry_msgs/TransformStamped[] transforms\n" SEP                                                      \
    "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n"                   \
    "geometry_msgs/Transform transform\n" SEP H SEP                                                          \
    "MSG: geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n" SEP \
    "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n" SEP                                       \
    "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"

const char *sooc_ros_definition(const char *type, sooc_msg_encoding enc) {
    char b[160];
    int r2 = enc == SOOC_MSGENC_CDR;
    sooc_ros_type_base(type, b, sizeof b);
    if (!strcmp(b, "sensor_msgs/Image")) return r2 ? IMAGE(HEADER2) : IMAGE(HEADER1);
    if (!strcmp(b, "sensor_msgs/CompressedImage")) return r2 ? CIMAGE(HEADER2) : CIMAGE(HEADER1);
    if (!strcmp(b, "sensor_msgs/CameraInfo"))
        return r2 ? CAMINFO(HEADER2, "d", "k", "r", "p") : CAMINFO(HEADER1, "D", "K", "R", "P");
    if (!strcmp(b, "tf2_msgs/TFMessage")) return r2 ? TFMSG(HEADER2) : TFMSG(HEADER1);
    return "";
}
