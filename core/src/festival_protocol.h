// What the caller (festival_tts.cpp, in avsi_core) and the Festival server
// (festival_server.cpp, the avsi-festival executable) say to each other over
// their SOCK_SEQPACKET socket and the answer pipes (wire.h encoding). Both
// ends come from the same build. See docs/tts.md ("Festival").
#pragma once

#include <cstddef>
#include <cstdint>

namespace avsi::detail::festival_protocol {

// The server's end of the socket is this descriptor when it starts.
constexpr int k_server_fd = 3;
// Longest text one request carries (it travels in one socket message).
constexpr std::size_t k_max_text_bytes = 64 * 1024;

// A request: i64 kind, str voice, str text; sent with the write end of a pipe
// (SCM_RIGHTS), into which one worker writes the whole answer.
// Transcribe: text is words, one a line; the answer (after Ok) is str phone
// set, i64 n, then per word i64 in_lexicon and i64 m phones, each str name
// and i64 stressed (the stress of its syllable).
enum RequestKind : std::int64_t { Synthesize = 1, ListVoices = 2, VoiceInfo = 3, Transcribe = 4 };

// An answer starts with a status:
//   Ok            then the request's result
//   UnknownVoice  then i64 n and n str: the installed voices (the caller says
//                 which one was meant)
//   Failure       then str: what failed, with Festival's own message
enum Status : std::int64_t { Ok = 0, UnknownVoice = 1, Failure = 2 };

// Written by the server on the socket once festival_initialize is done.
constexpr char k_ready = 1;

}  // namespace avsi::detail::festival_protocol
